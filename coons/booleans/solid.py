"""Booleans of solids bounded by trimmed surfaces: union, difference and intersection keeping the exact surfaces.

:func:`union`, :func:`difference` and :func:`intersection` combine any valid solids of coons
(faces on planes, cylinders, cones, spheres, tori or NURBS surfaces) and return a checked solid
whose faces keep their operands' surfaces (a box minus a cylinder has a cylindrical hole, not a
faceted one) and whose new edges are the exact or fitted surface–surface intersection curves.
When both operands are polyhedral (every face planar, every edge straight) the exact polyhedral
Booleans of :mod:`coons.booleans.polyhedral` are used instead (``method="auto"``).  The module
does not repair invalid operands, does not produce non-manifold results (they raise at
``"sew"``) and does not fuse faces across different surfaces.

Notation
--------
``A``, ``B``
    The operands; ``R`` the result.  ``X`` is a face of A, ``Y`` a face of B, each a
    :class:`~coons.topology.sew.FaceSpec` (surface, sense, loops of EdgeSpecs with p-curves).
face pair ``(i, j)``
    Face ``i`` of A and face ``j`` of B whose space boxes (``_new_face_data``: the boxes of the
    face's edge curves joined with the surface's interior extremes over the face, padded by the
    edge tolerances and ``tol.linear``) overlap.
parameter box
    The bounding box of a face's trim loops in its surface's parameter plane, enlarged by 1 %
    but never past a sphere's pole or a cone's apex (beyond them the parametrisation covers the
    same points again): the region :func:`~coons.kernel.intersect.intersect_surfaces` must search.
cut
    An :class:`~coons.topology.sew.EdgeSpec` lying inside a face along which the face is split:
    a piece of an intersection curve (the SAME curve object on X and on Y, each with its own
    p-curve), or an edge of the other operand imprinted onto a coincident face.
piece
    A face of A or B after splitting; its interior lies entirely inside, outside or on the other
    solid.
status
    ``OUT`` / ``IN``: the piece lies outside / inside the other solid; ``ON_SAME`` /
    ``ON_OPPOSITE``: it lies on a coincident face of the other solid whose outward normal points
    the same / the opposite way.

Phases (each a private function; a failure raises ``BooleanError(stage=..., diagnostics=...)``)
------------------------------------------------------------------------------------------------
1. ``_operands``, ``_Operand`` (stage ``"input"``): :func:`~coons.topology.sew.face_specs` of each solid, with
   implicit planes given a Newell plane and missing p-curves computed by
   :func:`~coons.kernel.onsurface.pcurve_on`; face boxes in space and in the parameter plane
   (sampled p-curves).  A space box (``_new_face_data``) holds the exact face without tessellating
   it: the box of its edges' curves (:func:`~coons.kernel.curve_intersect.curve_box`) holds the
   image of the trim boundary, and a coordinate's extremes inside the face are critical
   points, which add nothing on planes, cylinders and cones (a coordinate is affine along a
   ruling, so constant along the ruling through a critical point, up to the boundary), are the
   points with normal ``±e_k`` (and the poles) on spheres and tori, and are bounded by the
   control points of the spans the face covers on NURBS surfaces; a face with an edge curve
   or a surface of another type takes its box from the operand's tessellation instead.  The
   pipeline tessellates an operand only when its classifier is first needed (``_Operand.mesh``).
   A face of an earlier Boolean's result that :func:`~coons.topology.sew.sewn_unchanged`
   confirms is exactly the spec it was sewn from (``sew.sewn_from``) is that spec, with its per-face
   data (``_FACE_DATA``, its space box included) already computed.  The face data missing for
   either operand is computed in one batch for both (``_operands``).
2. ``_broad_phase``: overlapping face boxes, as one overlap table for up to ``_BROAD_TABLE`` face
   pairs, else by the implicit BVHs of :mod:`._broad_phase`.
3. ``_intersect`` (stage ``"intersect"``): per pair, ``intersect_surfaces(Sx, Sy, box_x, box_y)``
   (plane–cylinder pairs whose plane is perpendicular to the axis — a plate's faces against the
   walls of its holes — all at once first: ``_batched_sections``, the closed-form circles of
   :func:`~coons.kernel.intersect._plane_cylinder_circles`, and for their branches the clips,
   length tests and end tolerances below in array passes over all of them, ``_batched_pieces``;
   a pair the batch does not cover plainly, clear of every near-tie, takes the per-pair path);
   a branch recording a deviation above ``10 tol.linear`` has each p-curve that strays from its
   3-D curve rebuilt by ``pcurve_on`` (``_refitted``: a fit gone wrong near a pole must not
   widen the cut's tolerance to the size of the face); every branch is clipped to both
   trimmed faces (``clip_to_face``; in closed form by ``_clip_straight`` when a straight
   p-curve crosses a plane or cylinder face bounded by straight p-curves properly, far from its
   vertices, or stays clear of them; answered at once by ``_clip`` when the sampled p-curve's
   box meets no loop segment's box: the branch is then wholly inside or outside) and the common
   sub-ranges become cuts — on X where the piece runs inside X (not along X's boundary), on Y likewise.
   Coincident surfaces imprint each face's boundary edges onto the other (``pcurve_on`` of the
   edge curve on the other surface, ``clip_to_face``).  Isolated tangent points split nothing.
   Cuts repeated by several pairs (a curve along an edge of the other operand meets both faces of
   that edge) are kept once.  Cuts along the other operand's edges can also overlap with
   different ends (the section of a face, blind to the vertices of the edge chain it runs along,
   beside that chain's imprint from a coincident face): they are first split at each other's ends
   (``_split_overlaps``), so that the overlaps become repeats.  A cut's tolerance is widened to ``δ / sin φ`` at ends where it
   crosses a boundary edge at a small angle ``φ`` (both faces compute that point independently).
   Every cut end must meet another cut end, the face's boundary or an edge of the other operand;
   a dangling end means a missing branch and raises here rather than as an open shell later
   (``_check_cut_ends``; a face whose cut ends the end tolerance already found on its boundary,
   with a margin for round-off, needs no check).  The small inputs of a face crossed by a few
   branches (its polygon's sides, the cut ends, the midpoints of its cuts) are handled in Python
   floats by the array paths' own expressions, or decided where round-off cannot change the
   decision and left to the arrays where it could, so that every cut, tolerance and link is the
   same bit for bit (``tests/booleans/test_solid_intersect_paths.py``).  The batched pairs repeat
   the per-pair expressions on stacked arrays; they promise the same cuts to round-off only
   (the tests find them the same bit for bit up to the signs of zeros in circle frames).
4. ``_split`` (stage ``"split"``): ``split_face`` of every face with cuts (or, when the cuts
   form separate simple closed cycles clear of the face's loops — a hole drilled through a
   plate — ``_split_islands`` builds the holed face and one island per cycle directly, testing
   all cuts and all cycles of the face in array passes; when the cuts are straight chords
   across a straight-sided plane or cylinder face — a hole's wall crossing a plate —
   ``_split_chords`` splits the loop at the chords' ends directly, the chord tests of all the
   operand's faces run first in one pass, ``_chord_data``); each cut of ``split_face``'s
   pieces must then bound two pieces (its range used twice), unless it belongs to a dangling tree (a chain with an
   end inside the face, as a line of tangent contact), which ``split_face`` rightly drops (the two
   direct splits put every cut into two pieces by construction, and are not checked).
5. ``_classify`` (stage ``"classify"``), cheapest way first.  *Local*: a piece bounded by a
   cut along a branch stretch that lies inside both faces of its pair (a ``_Link`` recorded by
   ``_intersect``; none for a branch repeated by two faces of the other operand, i.e. along its
   edge) takes its side from the first-order geometry at a point ``q`` of that cut: with ``T``
   the cut's tangent in the piece's loop direction and ``N`` the outward normals,
   ``d = N_X × T`` points into the piece, which is IN when ``d · N_Y < 0``; used only where the
   surfaces cross at an angle (``|sin| >= 1e-2``) and ``q`` is clear of the other face's loops,
   in rounds of one candidate per undecided piece, each round one array pass with curves and surfaces
   evaluated by type, each piece's candidates found only as its rounds come (``_local_status``);
   both operands' rounds run together, one pass per round (``_local_both``, before ``_classify``).
   *Far* (first of all): a face whose box lies outside the other operand's box is OUT.
   *Propagated*: a face in no broad-phase pair (it and its edges are away from the other
   boundary) takes the status of a classified piece across one of its edges (``_propagate``).
   *By a point*, the rest (tangent contact, coincident faces, faces near the other boundary
   but not cut, whole shells far from it): one interior point per piece (the sample of a
   grid over the piece's parameter box that lies inside the trim polygon farthest from its
   boundary, mapped to space; the first grid of all pieces in array passes,
   ``_interior_points``) against the other solid by
   :class:`~coons.booleans.classify.Classifier` (winding number far from the boundary, exact
   projection near it); a point *on* the other boundary compares the outward normals.  Pieces
   of free faces are classified by their first vertex instead (they are far from the other
   boundary), and the classifier builds its per-face data only for faces near the query
   points, on the operand's own tessellation.  ``tests/booleans/test_local_classification.py``
   holds the first two ways to the third on the seeded pairs of the OCCT comparison.
6. ``_select`` by the table (B's kept pieces reversed in a difference: sense flipped, loops
   reversed, each EdgeSpec's ``t0, t1`` swapped)

   ============  ==========  ============  ===================
   operation     A pieces    B pieces      coincident pieces
   ============  ==========  ============  ===================
   union         OUT         OUT           ON_SAME, once (A's)
   intersection  IN          IN            ON_SAME, once (A's)
   difference    OUT         IN, reversed  ON_OPPOSITE (A's)
   ============  ==========  ============  ===================

7. ``_split_edges_at_vertices``: every vertex of the selected faces lying inside another edge
   use splits it (a T-junction: a cut ends on an edge of one face while the face across that
   edge received no cut, e.g. a sphere whose meridian lies in a box face).  An operand's
   unchanged face is tested only against vertices of other faces within its box.
8. ``_merge``: neighbouring selected faces on the same surface (the same object, ``is_close``,
   or the same point set in another parametrisation — the second face's p-curves are then
   recomputed on the first's surface by ``pcurve_on`` and shifted by whole periods to join it)
   with the same outward normal become one face (the shared edge disappears), unless the union
   would span a full period of a periodic parameter (coons has no seams, ``docs/brep.md``).
   That full-period test is decided for all candidate pairs on one periodic surface at once
   (``_wrapping_pairs``: the two half walls of every drilled hole), the same expressions as
   the pair-by-pair test, which runs for the other pairs; pairs remembered unmergeable
   (``_MERGE_FAILED``) are dropped before it.  Two faces on distinct planes are rejected from
   their boundary points in floats (``_off_plane``: a box's own edges) before ``_moved_to``.
9. ``_fuse_edges``: at a vertex where exactly two edges meet and continue one curve (the same
   curve object over adjacent ranges, or collinear lines), the two edges become one.
10. ``_sew`` (stage ``"sew"``): :func:`~coons.topology.sew.sew_faces`, which runs the checker.
   An empty selection is :meth:`Solid.empty() <coons.topology.shape.Solid.empty>`.  A result
   touching itself at a point raises naming the point (``_pinch``, see below).

Status and limitations
----------------------
* Depends on ``coons.kernel.intersect`` (exact analytic pairs), ``coons.kernel.ssi`` (marching,
  through the dispatcher), ``coons.kernel.onsurface`` and ``coons.topology.split``.
* Tested (``tests/booleans/test_solid_booleans.py``) against closed forms to ``1e-7`` relative
  (most agree to ``1e-15``; fitted curves — crossing cylinders of different radii, in closed form
  where every ruling of one crosses the other (a pipe right through another, ``_crossing_cylinders``
  in ``kernel.intersect``) and marched otherwise, offset spheres — to ``1e-8``; equal crossing cylinders, the Steinmetz solids, are exact ellipses) and against OCCT; OCCT itself is off by ``1e-5`` on crossing cylinders
  and offset spheres and wrong on a few (a lens of spheres along x, torus ∪ cylinder).
* Classification is local at transversal cuts and propagated to faces far from the other
  solid; only the remaining pieces (tangent contact, coincident faces, uncut faces near the
  other boundary, shells far from it) take one point each, all of an operand in one
  vectorised call.  Propagation does not cross edges of faces near the other solid.
* Cost: an operand is tessellated only when its classifier is needed (``_Operand.mesh``: some
  piece not decided locally, by propagation or by boxes); a Boolean still costs the whole of
  both operands in ``sew_faces`` (vertex clustering, matching and the topological checks over
  all faces), and array passes over all edge uses in the T-junction, merge and fuse passes,
  so sequential cuts into a large part still grow with its size, if slowly (the figures against
  OCCT: ``benchmarks/results/booleans_brep.md``).
  Carried from Boolean to Boolean (all keyed weakly by immutable objects, so a result never
  depends on what ran before, only the time does; ``tests/booleans/test_solid_booleans.py``
  compares warm and cold chains): a result remembers the completed face specs it was sewn
  from (``sew.sewn_from``), and the next Boolean takes every face whose B-rep row is exactly its spec
  (same surface, curve and p-curve objects, ranges and tolerances: ``sewn_unchanged``) with
  that spec's parameter box, space box, rings and segments (``_FACE_DATA``, assembled from
  per-loop data ``_LOOP_DATA``: a plate face gaining a hole reads its other loops' rings,
  segments and boxes from there, and a face of more than 16 loops the per-face reductions of
  the face of 16 loops or more that it extends, ``_FACE_PREFIX``); loop samples and
  space boxes are cached per edge use (``_USE_SAMPLES``, ``_USE_BOXES``), which the pieces of a
  split face keep (a split face's new space box joins its kept edges' boxes); a pair of face
  specs found unmergeable is not tried again (``_MERGE_FAILED``), the faces the last merge returned are
  not searched against each other again (``_MERGE_SETTLED``: a cut searches only its new faces' uses), nor
  a face spec found not to lie on another face's surface (``_NOT_ON``).  The end and mid points of a face's uses are
  one table per face spec (:func:`~coons.topology.sew.use_points`), read by the T-junction,
  merge and fuse passes and by sewing; the checker remembers its same-parameter measurements
  per curve, p-curve, surface and range (:mod:`coons.topology.check`), so the faces carried
  over are not sampled again, and skips the trim checks and same-parameter comparisons of a
  face whose spec passed an earlier clean check (a face extending such a spec by new loops has
  only its new loops' segment pairs tested); sewing records which faces equal their spec (in arrays, while sewing),
  which the next Boolean reads instead of comparing the B-rep with the specs; every other
  invariant is verified on the whole result.  The cyclic garbage collector is paused over
  every Boolean and over every public union, difference and intersection call (``_collector_paused``).  Where the time goes and what is left: ``docs/performance.md``.
  Reused as well: an operand's mesh when it was tessellated before (meshes are cached per
  B-rep; a result with voids shares the mesh its void nesting made, when it made one).  Local: the face boxes of
  the broad phase (per face spec, from its edges, no tessellation); the end tolerance of a cut
  and the T-junction pass only look at boundary edges whose box
  (:func:`~coons.kernel.curve_intersect.curve_box`) is near the points in question, and the
  T-junction pass finds the vertices near an unchanged face's box through a k-d tree.
* Tangent contact along a curve gives cuts like any other branch; results touching themselves
  along a curve are non-manifold and raise at ``"sew"`` (a cylinder hole tangent to the outer
  wall).  Lumps touching at a point inside their faces (two spheres) stay separate shells.  An
  isolated tangent point cuts nothing; where the result then touches itself at that
  point (a pinch: a box face tangent to a torus tube at a saddle point, whose section is a
  lemniscate with its two lobes meeting there) it is not a manifold and raises at ``"sew"``
  with the point and the number of fans, as the polyhedral Booleans do (OCCT returns the
  pinched solid).  Where such a contact lies inside faces and meets no edge of the other side
  (a void sphere touching its outer sphere inside both faces; a cylinder hole internally tangent
  to a wider cylinder's wall along a line clear of its seams) nothing is shared topologically:
  the result comes back with the right volume, touching itself, and the check does not see it
  (it compares topology and each face's own trims, not distances between faces).
* Singular intersection curves other than the equal cylinders' ellipses are marched and raise
  a ``BooleanError`` (at ``"split"`` or ``"intersect"``) in configurations found failing:
  cylinders of different radii touching at a point (the thin one internally tangent to the
  thick one, a double point of their quartic: with the thin one's half-face boundaries turned 20°
  about its axis, ``Cylinder(2, 10) + Cylinder(0.5, 10, direction=(1, 0, 0)).rotate(..., 20°)
  .translate((0, 1.5, 0.3))`` raises "not a manifold" at ``"sew"`` although the union is one, and
  the difference, which pinches there, comes back touching itself; at 0° both are right), and
  nearly equal cylinders (radii and axes off by
  more than a quarter of ``tol.linear``, ``kernel.intersect._EQUAL_CYLINDERS_GAP``, so marched)
  whose axes pass about ``1e-4`` apart (two near-touching branches).
* Chains of Booleans in special position (cylinders, boxes turned 30° or 45° and spheres on a
  0.25 grid, many sharing cap planes, compared with OCCT and a Monte Carlo referee by
  ``benchmarks/hunt_boolean_chains.py``; the fixed configurations are tests in
  ``tests/booleans/test_solid_regressions.py``) raise a ``BooleanError`` in no found case
  other than the by-design ones above.  In the same runs OCCT returned wrong volumes (2–120 % off the referee) in chains where coons agreed with the
  referee.  Fixed since: a cut running along a boundary edge of its face (the same circle, from an
  earlier Boolean with a shared cap plane) widened its end tolerance 1000-fold per Boolean until a
  short cut was dropped (:func:`_runs_along`); a straight and a curved p-curve of one shared edge
  compared at two and three points in the merge (a ``ValueError``); a marching grid crossing a
  branch twice in one cell near its extreme, both crossings corrected onto one root (the fitted
  section ran back and forth: ``kernel.ssi``); the classifier's edge rule taking a farther edge for
  a point in the plane of a face, in its hole (an open result); a section loop touching a half
  sphere's bounding meridian to fourth order, ordered against it at the node by a curvature below
  the fit's accuracy (``split_face`` now asks on which side of a straight boundary the curve lies a
  little farther along); a cylinder inside a wider one, tangent to its wall along a line (seed 41),
  whose cap is split by the narrower rim into a disc and a crescent pinched where the rims touch:
  ``split_face`` took the wider rim run backwards (the outside of the cap) for a hole of the disc
  when the contact was the rim's seam vertex, and the check's sampled trims crossed where the
  crescent's loop touches itself (its last refinement now samples towards the edges' ends; the
  same for a cylinder wall whose section with a sphere is tangent to the sphere's seam meridian
  near the pole, seed 10); rims
  of different radii internally tangent to 1e-5 beside a seam vertex (the same backward run taken
  for a hole); a cylinder inside another, tangent to its wall along a line that meets the outer
  one's cap, and a box side tangent to a cylinder wall along a line that meets another cylinder's
  cap plane: the cap's split put the node where two rims touch 1.2e-6 from the vertex the walls'
  tangent line gives (Newton on the squared distance stops about ``sqrt(eps / Δκ)`` along tangent
  curves; two circles now meet in closed form, ``kernel.curve_intersect._circle_circle``), and the
  batched end tolerance lacked :func:`_runs_along` (cuts along an earlier Boolean's circle took 0.1);
  a sphere–cylinder section touching the plane of the sphere's seam meridians where a box side
  crosses both (seed 46): the 5.5e-5 sliver of the fitted section on the far half sphere runs along
  that half's boundary and, on the cylinder, along the near half's section piece; ``split_face``
  dropped it on both faces, rightly, and the check of the cuts' use raised (it now accepts a dropped
  cut lying along the face's edges or its other cuts, :func:`_along_edges`); a sphere centred on a
  cylinder's seam line (seed 48): its section runs through both poles, and the marching of the far
  half took its longitudes a turn off the face's box from the value Newton left at the pole where it
  started (``kernel.ssi._determined`` now moves a piece's periodic parameters by whole periods into
  the box); a sphere–cylinder section osculating the sphere face's bounding meridian to fourth
  order (seed 23): ``split_face`` lets the meridian serve over the cut's first 0.006, and the check
  of the cuts' use now accepts a cut used fewer than twice only where it runs along the face's edges
  or its other cuts (:func:`_short_of_two`); a box side touching the lens of a cylinder and a sphere
  along the wall's line from the box's edge to where the lens's rim touches the side (seed 49): the
  sphere face's section with the side, clipped to the face, is a sliver shorter than its own end
  tolerance at the line's inner end, and the check of the cuts' use took it for a joint that made
  the dangling line a path from the boundary (every Boolean raised; :func:`_free_chains` now takes
  such a cut for a point).  The union there touches itself along the line, as above.  A cylinder
  across ``Cylinder(2)`` whose wall touches the plane of the wider one's half-face boundary lines
  (any radius from 0.7 up): the section ends on those lines tangent to them, and the face split's
  re-solve of that crossing in space slid along the tangency by ``sqrt(gap / curvature)``, up to
  4.5e-5 off the vertex the section's other faces have (an open shell); and a sphere–sphere circle
  cut at the small sphere's meridian near the big one's pole (seed 59, one Boolean), whose two
  arcs lie within tolerance over 4e-8 about their shared end, which the curve intersection
  reported as an overlap and the split left as a sliver piece.  ``split_face`` now takes a
  crossing within ``tol3`` of a cut's end for that end and an overlap no longer than ``tol3`` for
  a touching (``coons.topology.split._in_space``, ``_touching_overlaps``).  A cylinder wall touching
  a box side from inside along a line from the edge of a hole in that side to its outer edge (seed
  63): ``split_face`` drops the line (one region on both sides) and the check of the cuts' use took a
  chain with both ends on the boundary for a separating path (:func:`_free_chains` now lets a chain
  bridge loops not yet joined).  A sphere internally tangent to a cylinder wall at a corner of its
  half faces (on a boundary line and the rim; seed 61, one Boolean): the double point of the section
  lay one cell inside the marching grid's padded box, the grid joined the arm inside the face to the
  arm beyond it, and the branch reached the corner from outside the face (``kernel.ssi`` now splits a
  chain that ends a cell past a singular point on its segment nearest the point).
* Edges are fused back only along one curve object or collinear lines: two co-circular arcs
  of different Circle objects keep the vertex between them.
* Disjoint operands need no special case: every face is one piece classified against the other.
* n-ary calls: ``difference(a, t0, t1, ...)`` and ``union(s0, s1, ...)`` first gather operands
  whose bounding boxes are pairwise apart into one solid (their B-reps side by side,
  :func:`~coons.topology.disjoint.stacked`, as :func:`~coons.topology.disjoint.disjoint_union`
  makes them: no sewing, no Boolean among them, and their face specs handed on through
  ``sew.sewn_from``) and run one pipeline pass per such group (a plate minus 100 separate
  cylinders is one pass; the tools' padded boxes are one array pass,
  :func:`~coons.topology.disjoint.padded_boxes`, and when no two meet they are one group
  without the greedy grouping); otherwise and for ``intersection`` they fold left:
  ``(a ∪ b) ∪ c``.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import itertools
import logging
import math
import operator
import weakref

import numpy as np

from coons.booleans._broad_phase import box_pairs
from coons.errors import BooleanError, CoonsError, InvalidInputError
from coons.kernel._common import linspace_rows, row_groups, row_norms, used_ids
from coons.kernel.analytic import (Circle, ConicalSurface, CylindricalSurface, Ellipse, Line, PlanarSurface,
                                   surface_derivatives, surface_normals)
from coons.kernel.curve import NurbsCurve
from coons.kernel.intersect import _cross, _pcurve_points
from coons.kernel.onsurface import curve_derivatives, evaluate_curves
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.polygon import proper_crossings
from coons.tolerance import Tolerance, resolve
from coons.topology._memo import IdentityMemo, found_by_id, id_index, is_value, read_only as _frozen
from coons.topology.brep import BRep
from coons.topology.disjoint import meeting_pair, padded_boxes, stacked
from coons.topology.sew import (EdgeSpec, FaceSpec, _face_uses, _gathered_uses, face_specs, face_specs_many,
                               point_clusters, read_unchanged_faces, remember_sewn, sew_faces, sewn_from,
                               sewn_unchanged_faces, use_points)
from coons.topology.shape import Solid

__all__ = ["union", "difference", "intersection", "boolean", "is_polyhedral", "reversed_face",
           "OUT", "IN", "ON_SAME", "ON_OPPOSITE"]

_log = logging.getLogger("coons")

OUT, IN, ON_SAME, ON_OPPOSITE = 0, 1, 2, 3
_STATUS_NAMES = ("OUT", "IN", "ON_SAME", "ON_OPPOSITE")
#: Statuses kept from A, from B, and whether B's kept pieces are reversed.
_TABLE = {
    "union": ({OUT, ON_SAME}, {OUT}, False),
    "intersection": ({IN, ON_SAME}, {IN}, False),
    "difference": ({OUT, ON_OPPOSITE}, {IN}, True),
}
_METHODS = ("auto", "polyhedral", "brep")
#: Samples per curved edge when a loop is turned into a parameter-plane polygon (resolution only).
_LOOP_SAMPLES = 33
#: Relative enlargement of a face's parameter box handed to the surface intersection, so that
#: branches reaching the trim boundary are not cut short of it (clip_to_face trims exactly).
_BOX_MARGIN = 0.01


# ====================================================================== public API
def union(*solids: Solid, tol: Tolerance | None = None, method: str = "auto") -> Solid:
    """The union ``s0 ∪ s1 ∪ ...`` of solids with any faces.

    Parameters
    ----------
    *solids : Solid
    tol : Tolerance, optional
    method : {"auto", "polyhedral", "brep"}
        ``"auto"`` uses the exact polyhedral Booleans when both operands are polyhedral and the
        trimmed-surface pipeline otherwise; the others force one path.

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        No solids, a non-Solid argument, an unknown method.
    BooleanError
        A failed stage (``"input"``, ``"intersect"``, ``"split"``, ``"classify"``, ``"sew"``)
        with the faces involved in ``diagnostics``.

    Examples
    --------
    >>> from coons.topology.primitives import Box, Cylinder
    >>> r = union(Box(2, 2, 2), Cylinder(0.5, 4))
    >>> bool(abs(r.volume - (8 + 0.25 * np.pi * 2)) < 1e-9)
    True
    """
    return _fold("union", solids, tol, method)


def difference(a: Solid, *tools: Solid, tol: Tolerance | None = None, method: str = "auto") -> Solid:
    """``a − t0 − t1 − ...`` (see :func:`union` for the parameters and errors).

    Examples
    --------
    >>> from coons.topology.primitives import Box, Cylinder
    >>> r = difference(Box(10, 10, 10), Cylinder(3, 20))
    >>> bool(abs(r.volume - (1000 - 90 * np.pi)) < 1e-8), len(r.faces())
    (True, 8)
    """
    return _fold("difference", (a,) + tools, tol, method)


def intersection(*solids: Solid, tol: Tolerance | None = None, method: str = "auto") -> Solid:
    """The common part ``s0 ∩ s1 ∩ ...`` (see :func:`union` for the parameters and errors)."""
    return _fold("intersection", solids, tol, method)


def boolean(a: Solid, b: Solid, op: str, tol: Tolerance | None = None, method: str = "auto") -> Solid:
    """One binary Boolean, ``op`` in ``{"union", "intersection", "difference"}``.

    Raises
    ------
    InvalidInputError
        An unknown ``op`` or ``method``, or an operand that is not a Solid.
    BooleanError
        As :func:`union`.
    """
    if op not in _TABLE:
        raise InvalidInputError(f"op must be one of {sorted(_TABLE)}, got {op!r}")
    if method not in _METHODS:
        raise InvalidInputError(f"method must be one of {list(_METHODS)}, got {method!r}")
    for name, s in (("a", a), ("b", b)):
        if not isinstance(s, Solid):
            raise InvalidInputError(f"Boolean operand {name} must be a coons Solid, got {type(s).__name__}")
    return _dispatch(a, b, op, resolve(tol), method)


def _fold(op: str, solids: tuple, tol: Tolerance | None, method: str) -> Solid:
    t = resolve(tol)
    if method not in _METHODS:
        raise InvalidInputError(f"method must be one of {list(_METHODS)}, got {method!r}")
    if not solids:
        raise InvalidInputError(f"{op} needs at least one solid, got none")
    for i, s in enumerate(solids):
        if not isinstance(s, Solid):
            raise InvalidInputError(f"{op}: argument {i} must be a coons Solid, got {type(s).__name__}")
    # The collector paused over the whole call (as _dispatch pauses it over each Boolean, either engine): an
    # n-ary call's gathering of many tools allocates as the pipeline does (_collector_paused).
    with _collector_paused():
        return _folded(op, solids, t, method)


def _folded(op: str, solids: tuple, t: Tolerance, method: str) -> Solid:
    if op == "difference" and len(solids) > 2:
        out = solids[0]
        for group in _disjoint_groups(solids[1:], t):
            out = _dispatch(out, _gathered(group, t), op, t, method)
        return out
    if op == "union" and len(solids) > 2:
        groups = [_gathered(g, t) for g in _disjoint_groups(solids, t)]
        out = groups[0]
        for s in groups[1:]:
            out = _dispatch(out, s, op, t, method)
        return out
    out = solids[0]
    for s in solids[1:]:
        out = _dispatch(out, s, op, t, method)
    return out


def _disjoint_groups(solids, t: Tolerance) -> list[list[Solid]]:
    """The non-empty solids in groups whose bounding boxes are pairwise apart (by more than ``t.linear``).

    Greedy in argument order: each solid joins the first group none of whose members' boxes it
    meets, else starts a new one.  The solids of one group are disjoint, so their union is just
    their B-reps side by side (:func:`_gathered`); a difference or union by a group is then one
    pipeline pass instead of one per solid.  The result does not depend on the grouping (the
    Booleans are associative), only the cost does.
    """
    solids = [s for s in solids if not s.is_empty]
    if not solids:
        return [[Solid.empty()]]
    # Boxes closer than the tolerances could let sewing merge vertices of two solids (padded_box).
    box = padded_boxes(solids, t)
    if meeting_pair(box) is None:
        return [solids]  # (what the greedy pass below gives when no two boxes meet: a drilling grid)
    lo, hi = box[:, 0], box[:, 1]
    group = np.empty(len(solids), dtype=np.int64)
    groups: list[list[Solid]] = []
    for k, s in enumerate(solids):
        # The groups of the earlier solids whose boxes meet this one's (closed boxes) are barred.
        meets = np.all((lo[:k] <= hi[k]) & (lo[k] <= hi[:k]), axis=1)
        barred = np.zeros(len(groups) + 1, dtype=bool)
        barred[group[:k][meets]] = True
        g = int(np.argmin(barred))  # the first group not barred (a new one if all are)
        if g == len(groups):
            groups.append([])
        groups[g].append(s)
        group[k] = g
    return groups


def _gathered(group: list[Solid], t: Tolerance) -> Solid:
    """One solid made of the pairwise disjoint solids of ``group``: their B-reps side by side
    (:func:`~coons.topology.disjoint.stacked`, as :func:`~coons.topology.disjoint.disjoint_union`
    makes them, no sewing, no check: valid by construction).  ``group`` must be a group of
    :func:`_disjoint_groups`, whose padded boxes are pairwise apart: ``disjoint_union``'s test is
    not repeated here.

    The union's faces are the members' faces in order, on the very same geometry objects, so
    their face specs are handed on as the specs it was "sewn" from (``sew.sewn_from``): a member's own
    ``sewn_from`` specs when it is an earlier Boolean's result (their per-face data cached), else
    its :func:`face_specs` (:func:`~coons.topology.sew.face_specs_many`: a drilling pattern's tools
    are walked once); ``_Operand`` takes those :func:`sewn_unchanged_faces` confirms instead of
    reading the faces again (recorded here: the read ones by
    :func:`~coons.topology.sew.read_unchanged_faces`, the carried ones by the walk).  A union of
    polyhedral members hands on nothing (the polyhedral Booleans, which it most likely meets, read
    no face specs).
    """
    if len(group) == 1:
        return group[0]
    # (disjoint_union without its test: the group's padded boxes, the ones it tests, are apart)
    out = Solid(stacked([s.brep for s in group]))
    if all(is_polyhedral(s) for s in group):
        return out
    # A member's own sewn_from specs when it has them, else its face_specs, all read in one call
    # (face_specs_many: a drilling pattern's tools, one primitive placed again and again, walked once).
    sewn = [sewn_from(s.brep) for s in group]
    sewn = [x if x is not None and len(x) == s.brep.n_faces else None for x, s in zip(sewn, group)]
    read = iter(face_specs_many([s.brep for s, x in zip(group, sewn) if x is None]))
    specs: list[FaceSpec] = []
    carried: list[int] = []  # (the faces whose specs are a member's own sewn_from specs)
    for x in sewn:
        if x is not None:
            carried += range(len(specs), len(specs) + len(x))
            specs += x
        else:
            specs += next(read)
    # Which faces equal their spec: those read by face_specs in two array passes over the union
    # (read_unchanged_faces), the carried ones by the walk (a member's sewing may have changed them).
    unchanged = read_unchanged_faces(out.brep)
    if carried:
        unchanged[carried] = sewn_unchanged_faces(out.brep, [specs[f] for f in carried], rows=carried)
    remember_sewn(out.brep, specs, unchanged)
    return out


def is_polyhedral(s: Solid) -> bool:
    """Whether every face of ``s`` is planar (surface None or PlanarSurface) and every edge straight."""
    b = s.brep
    # used_ids: the distinct references by a scatter (np.unique sorts: ~7 ms for two 1e5-face meshes).
    surf_ok = all(isinstance(b.surfaces[int(i)], PlanarSurface) for i in used_ids(b.face_surface, len(b.surfaces)))
    curve_ok = all(isinstance(b.curves[int(i)], Line) for i in used_ids(b.edge_curve, len(b.curves)))
    return surf_ok and curve_ok


def _dispatch(a: Solid, b: Solid, op: str, t: Tolerance, method: str) -> Solid:
    with _collector_paused():  # (either engine: a no-op inside _fold's pause)
        if method == "polyhedral" or (method == "auto" and is_polyhedral(a) and is_polyhedral(b)):
            from coons.booleans import polyhedral

            return polyhedral.boolean(a, b, op, t)
        return _boolean(a, b, op, t)


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off for the duration (when it was on).

    The pipeline allocates many small objects (edge uses, face specs, memo entries) that live on
    with the result, and the collector's full passes over a large part's heap find nothing to
    collect: measured on 400 sequential cuts into a plate, 34 full passes cost 9% of the time.
    The objects made here are freed by reference counting; any cycle among them is collected
    by the first collection after the Boolean.  The collector is switched back on by the call
    that switched it off (a nested or concurrent Boolean that finds it off leaves it alone).
    """
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


# ====================================================================== the pipeline
def _boolean(a: Solid, b: Solid, op: str, t: Tolerance) -> Solid:
    """Phases 1–10 (see the module docstring)."""
    if a.is_empty or b.is_empty:
        if op == "union":
            return b if a.is_empty else a
        if op == "intersection":
            return Solid.empty()
        return Solid.empty() if a.is_empty else a
    A, B = _operands(a, b, t)
    I, J = _broad_phase(A, B)
    links: dict[int, list[_Link]] = {}
    cuts_a, cuts_b = _intersect(A, B, I, J, t, links)
    pieces_a = _split(A, cuts_a, t)
    pieces_b = _split(B, cuts_b, t)
    # (the local way of both operands in one pass, then each operand's other ways)
    local_a, local_b = _local_both(pieces_a, pieces_b, A, B, cuts_a, cuts_b, links, t)
    status_a = _classify(pieces_a, A, B, t, free=_unpaired(len(A.specs), I), cuts=cuts_a, links=links, side=0,
                         local=local_a)
    status_b = _classify(pieces_b, B, A, t, free=_unpaired(len(B.specs), J), cuts=cuts_b, links=links, side=1,
                         local=local_b)
    faces = _select(op, pieces_a, status_a, pieces_b, status_b)
    if not faces:
        return Solid.empty()
    # Faces passed through unchanged: their operand (1 for A, 2 for B) and index there (the padded
    # space boxes are the operands' rows).
    orig = {id(spec): (1, f) for f, spec in enumerate(A.specs)}
    orig.update({id(spec): (2, f) for f, spec in enumerate(B.specs)})
    # Edge uses passed through unchanged (split faces keep the EdgeSpec objects of their untouched
    # edges): their operand.  Only uses of faces that are not passed through whole are looked up,
    # and those come from split faces (a piece keeps uses of its own face only): all of B's, then
    # A's split faces (B's entry wins for a use in both, the first found by id; B is the tool, and
    # A, a part cut many times, has thousands of uses on faces no cut touched).
    split_a = {f for f, spec in pieces_a if spec is not A.specs[f]}
    uses_b = [e for spec in B.specs for loop in spec.loops for e in loop]
    uses_a = [e for f in split_a for loop in A.specs[f].loops for e in loop]
    orig_edges = (*id_index(uses_b + uses_a), np.repeat([2, 1], [len(uses_b), len(uses_a)]))
    # (the uses' end and mid points: per face spec, sew.use_points, read by the three passes and sewing)
    faces = _split_edges_at_vertices(faces, t, orig, orig_edges, {1: (A.lo, A.hi), 2: (B.lo, B.hi)})
    faces = _merge(faces, t)
    faces = _fuse_edges(faces, t)
    return _sew(faces, t)  # (which records the specs the result was sewn from: sew.sewn_from)


class _Operand:
    """Face specifications of one operand, completed for the pipeline, and their boxes.

    Attributes
    ----------
    specs : list of FaceSpec, every face with a surface and every edge use with a p-curve
    lo, hi : (F, 3) space boxes of the faces (:func:`_new_face_data`), padded by their edge tolerances and ``t.linear``
    uv_box : list of ((u0, u1), (v0, v1)) enlarged parameter boxes
    """

    def __init__(self, solid: Solid, name: str, t: Tolerance, specs: list[FaceSpec] | None = None,
                 data: list["_FaceData"] | None = None) -> None:
        # (``specs`` and ``data``: :func:`_operands`, which computes both operands' face data together)
        self.solid, self.name, self.t = solid, name, t
        b = solid.brep
        F = b.n_faces
        if specs is None:
            specs = _operand_specs(solid, name, t)
        self.specs: list[FaceSpec] = specs
        self._data: list[_FaceData] = _face_data_many(specs, t) if data is None else data
        self.uv_box = [d.uv_box for d in self._data]
        self.polygons = [d.rings for d in self._data]
        self.segments = [d.seg for d in self._data]
        self.seg_lo = [d.seg_lo for d in self._data]
        self.seg_hi = [d.seg_hi for d in self._data]
        # Space boxes from each face's own geometry (:func:`_new_face_data`, cached with its data: a
        # face carried over unchanged from an earlier result costs nothing here); the rare face
        # without a proven box (an edge curve curve_box does not bound, a surface type
        # _interior_extremes does not know) takes its box from the operand's tessellation.
        no_box = [f for f, d in enumerate(self._data) if d.box is None]
        if no_box:
            mesh_box = self._mesh_boxes()
            box = np.concatenate([mesh_box[f] if d.box is None else d.box for f, d in enumerate(self._data)])
        else:
            box = np.concatenate([d.box for d in self._data]) if F else np.empty((0, 3))
        # (the (2, 3) boxes joined and viewed as (F, 2, 3): np.stack's per-array reshaping costs three times more)
        box = box.reshape(-1, 2, 3)
        self.lo, self.hi = box[:, 0], box[:, 1]
        self._classifier = None

    @functools.cached_property
    def mesh(self):
        """The operand's tessellation at the tessellator's default deflection, made on first use
        (by the classifier, or for a face without a proven box); cached per B-rep by ``tessellate``."""
        from coons.topology.tessellate import tessellate

        return tessellate(self.solid, tol=self.t)

    def _meshed(self, stage: str, why: str):
        """:attr:`mesh`, a failure of the tessellator reported as a ``BooleanError`` of ``stage``."""
        try:
            return self.mesh
        except (CoonsError, ValueError, ArithmeticError) as exc:
            raise BooleanError(
                f"operand {self.name}: its tessellation ({why}) failed: {type(exc).__name__}: {exc}",
                stage=stage, diagnostics={"operand": self.name, "error": str(exc)},
            ) from exc

    def _mesh_boxes(self) -> np.ndarray:
        """``(F, 2, 3)`` face boxes from :attr:`mesh`, padded by its deflection, the edges'
        tolerances and ``t.linear`` (the exact face lies within that of its triangles)."""
        mesh, b = self._meshed("broad_phase", "for face boxes"), self.solid.brep
        F = b.n_faces
        diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
        # The tessellator's default deflection is 1e-3 of the diagonal.
        pad = 1e-3 * diag + float(np.max(b.edge_tol, initial=0.0)) + self.t.linear
        lo = np.full((F, 3), np.inf)
        hi = np.full((F, 3), -np.inf)
        X = mesh.vertices[mesh.triangles]
        np.minimum.at(lo, mesh.face_ids, X.min(axis=1))
        np.maximum.at(hi, mesh.face_ids, X.max(axis=1))
        return np.stack([lo - pad, hi + pad], axis=1)

    def edge_boxes(self, f: int) -> tuple[list[EdgeSpec], np.ndarray, np.ndarray, np.ndarray]:
        """Face ``f``'s edge uses in loop order, their space boxes ``lo, hi (k, 3)`` (:func:`_edge_boxes`,
        infinite where it gives none) and tolerances ``(k,)``, computed once per face spec."""
        d = self._data[f]
        if d.edge_boxes is None:
            self.fill_edge_boxes([f])
        return d.edge_boxes

    def fill_edge_boxes(self, faces: list[int]) -> None:
        """:meth:`edge_boxes` of the faces ``faces`` not computed yet, their tolerances in one array (the
        walls of a hundred holes: each face's are read-only views of it)."""
        todo = [f for f in dict.fromkeys(faces) if self._data[f].edge_boxes is None]
        if not todo:
            return
        edges = [[e for loop in self.specs[f].loops for e in loop] for f in todo]
        tol = _frozen(np.array([e.tol or 0.0 for es in edges for e in es], dtype=np.float64))
        at = 0
        for f, es in zip(todo, edges):
            d = self._data[f]
            # (the loops' stacked use boxes: one copy for a face of many holes; a face of one loop has them)
            if len(d.loops) == 1:
                lo, hi = d.loops[0].use_lo, d.loops[0].use_hi
            else:
                lo = np.concatenate([ld.use_lo for ld in d.loops]) if d.loops else np.empty((0, 3))
                hi = np.concatenate([ld.use_hi for ld in d.loops]) if d.loops else np.empty((0, 3))
            d.edge_boxes = (es, _frozen(lo), _frozen(hi), tol[at : at + len(es)])
            at += len(es)

    @property
    def classifier(self):
        """The :class:`~coons.booleans.classify.Classifier` of the operand, built on first use; its
        winding numbers need the whole tessellation (:attr:`mesh`), which is made only then."""
        from coons.booleans.classify import Classifier

        if self._classifier is None:
            self._classifier = Classifier(self.solid, self.t, mesh=self._meshed("classify", "for point classification"))
        return self._classifier


def _operands(a: Solid, b: Solid, t: Tolerance) -> tuple[_Operand, _Operand]:
    """The operands ``A`` of ``a`` and ``B`` of ``b`` (phase 1), their face data computed in one
    pass (:func:`_face_data_many`: one batch of samples, loop data and edge boxes instead of two;
    a box minus a cylinder pays the batches' fixed cost once)."""
    specs_a = _operand_specs(a, "A", t)
    specs_b = _operand_specs(b, "B", t)
    data = _face_data_many(specs_a + specs_b, t)
    n = len(specs_a)
    return _Operand(a, "A", t, specs_a, data[:n]), _Operand(b, "B", t, specs_b, data[n:])


def _operand_specs(solid: Solid, name: str, t: Tolerance) -> list[FaceSpec]:
    """The completed face specs of an operand (:class:`_Operand`), in face order.

    Faces of a Boolean result sewn unchanged from a completed spec are that spec (checked
    field by field, :func:`sewn_unchanged`); the others are read from the B-rep, with a
    surface and every edge use's p-curve.
    """
    from coons.booleans.classify import surface_of

    b = solid.brep
    F = b.n_faces
    specs: list[FaceSpec | None] = [None] * F
    sewn = sewn_from(b)
    if sewn is not None and len(sewn) == F:
        for f in np.flatnonzero(sewn_unchanged_faces(b, sewn)).tolist():
            specs[f] = sewn[f]
    missing = [f for f in range(F) if specs[f] is None]
    for f, spec in zip(missing, face_specs(solid, rows=missing) if missing else []):
        S = spec.surface if spec.surface is not None else surface_of(b, f)
        try:
            loops = [[_with_pcurve(S, e, t) for e in loop] for loop in spec.loops]
        except CoonsError as exc:
            raise BooleanError(f"operand {name}, face {f}: cannot compute the p-curves of its edges: {exc}",
                               stage="input", diagnostics={"operand": name, "face": f}) from exc
        specs[f] = FaceSpec(S, spec.sense, loops)
    return specs  # type: ignore[return-value]


#: Surface types whose parameter domain :func:`_within_domain` never clips (an infinite ``v`` range, and ``u``
#: infinite or periodic): it returns the box as given.
_WHOLE_DOMAIN = (PlanarSurface, CylindricalSurface)


def _within_domain(S, ub: tuple, vb: tuple, v_face: tuple) -> tuple[tuple[float, float], tuple[float, float]]:
    """The enlarged parameter box ``(ub, vb)`` clipped to where ``S`` is one-to-one.

    The margin must not carry a box past a sphere's pole (latitudes beyond ``±π/2`` are the
    points across the pole again, so the marching would find a mirrored copy of a branch that
    passes near the pole and join the two across it) or past a cone's apex onto the other nappe
    (``v_face`` is the face's own ``v`` range, which says which nappe).  Periodic and infinite
    directions are not clipped.
    """
    (u0, u1), (v0, v1) = ub, vb
    dom = getattr(S, "domain", None)
    if dom is not None:
        (du0, du1), (dv0, dv1) = dom
        if not getattr(S, "periodic_u", False):
            u0, u1 = max(u0, du0), min(u1, du1)
        if not getattr(S, "periodic_v", False):
            v0, v1 = max(v0, dv0), min(v1, dv1)
    if isinstance(S, ConicalSurface):
        v_apex = -S.radius / math.sin(S.semi_angle)
        if v_face[0] >= v_apex:
            v0 = max(v0, v_apex)
        elif v_face[1] <= v_apex:
            v1 = min(v1, v_apex)
    return (float(u0), float(u1)), (float(v0), float(v1))


def _with_pcurve(S, e: EdgeSpec, t: Tolerance) -> EdgeSpec:
    """``e`` with its p-curve on ``S`` (computed by ``pcurve_on`` when missing)."""
    if e.pcurve is not None:
        return e
    from coons.kernel.onsurface import pcurve_on

    lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
    pc, dev = pcurve_on(S, e.curve, lo, hi, tol=t)
    return EdgeSpec(e.curve, e.t0, e.t1, pc, max(dev, e.tol or 0.0))


def _edge_uv(e: EdgeSpec, S, n: int, *, all_n: bool = False) -> np.ndarray:
    """Parameter-plane samples ``(k, 2)`` of an edge use in its direction of travel: its two ends
    when its p-curve is straight (unless ``all_n``), else ``n``."""
    straight = isinstance(e.pcurve, Line2D) and not all_n
    tt = np.linspace(e.t0, e.t1, 2 if straight else n)
    if e.pcurve is not None:
        return np.asarray(e.pcurve.evaluate(tt), dtype=np.float64)
    return np.asarray(S.closest_parameters(np.asarray(e.curve.evaluate(tt))), dtype=np.float64)


def _edge_samples(spec: FaceSpec, n: int = _LOOP_SAMPLES) -> list[list[np.ndarray]]:
    """Per loop, the parameter-plane samples of each edge use (:func:`_edge_uv`; read-only arrays,
    cached per use and surface for the default ``n``)."""
    if n != _LOOP_SAMPLES:
        return [[_edge_uv(e, spec.surface, n) for e in loop] for loop in spec.loops]
    return [[_use_samples(e, spec.surface) for e in loop] for loop in spec.loops]


def _use_samples(e: EdgeSpec, S) -> np.ndarray:
    """:func:`_edge_uv` of ``e`` on ``S`` with ``_LOOP_SAMPLES``, cached per use (an EdgeSpec is immutable).

    The pieces of a split face and the faces a Boolean result carries over to the next Boolean
    (``sew.sewn_from``) keep the very EdgeSpec objects of their untouched uses: a plate face gaining one
    more hole does not sample the edges of its other holes again.
    """
    got = _USE_SAMPLES.get(e)
    if got is not None and got[0] is S:
        return got[1]
    Ue = _frozen(_edge_uv(e, S, _LOOP_SAMPLES))
    _USE_SAMPLES.set(e, (S, Ue, None))  # (the pad on demand, :func:`_use_samples_pad`)
    return Ue


def _prefill_samples(specs: list[FaceSpec], t: Tolerance | None = None, kept: list | None = None) -> None:
    """Fill :func:`_use_samples` (and the pads of :func:`_use_samples_pad`) for the uses of ``specs`` not sampled yet
    whose p-curve is a :class:`Line2D` or :class:`Trig2D`, all in one array pass
    (:func:`~coons.kernel.onsurface.curve_derivatives`, the p-curves' own formulas): the pieces of a
    Boolean bring many new cut edges.  With ``t``, the loops whose :class:`_LoopData` is cached are
    skipped (:func:`_cached_loop`; the kept loops of a face extending a kept one, :func:`_kept_prefix`,
    without a look-up each): their samples are not read again (a plate's top gaining a hole keeps
    a hundred loops).  ``kept``: per spec, its :func:`_kept_prefix` entry or None, when the caller
    has found them."""
    lines: list[tuple[EdgeSpec, object]] = []
    trigs: list[tuple[EdgeSpec, object]] = []
    for k, spec in enumerate(specs):
        S = spec.surface
        loops = spec.loops
        if t is not None and len(loops) > _PREFIX_LOOPS:
            got = _kept_prefix(spec, t) if kept is None else kept[k]
            if got is not None:
                loops = loops[len(got[1]) + 1 :]  # (their data is kept whole: _extended_face_data)
        for loop in loops:
            if t is not None and loop and _cached_loop(loop, S, t) is not None:
                continue
            for e in loop:
                got = _USE_SAMPLES.get(e)
                if got is not None and got[0] is S:
                    continue
                kind = type(e.pcurve)
                if kind is Line2D:
                    lines.append((e, S))
                elif kind is Trig2D:
                    trigs.append((e, S))
    for group, n in ((lines, 2), (trigs, _LOOP_SAMPLES)):  # (a straight p-curve: its two ends)
        if group:
            T = np.linspace([e.t0 for e, _ in group], [e.t1 for e, _ in group], n, axis=-1)
            # (read-only once: its rows, each use's samples, are read-only views)
            U = _frozen(curve_derivatives([e.pcurve for e, _ in group], T, 0, 2)[:, :, 0])
            if group is lines:
                pad = [0.0] * len(group)
            else:
                pad = row_norms(np.diff(U, axis=1)).max(axis=1).tolist()
            _USE_SAMPLES.set_many([e for e, _ in group], [(S, Ue, p) for (_, S), Ue, p in zip(group, U, pad)])


def _use_samples_pad(e: EdgeSpec, S) -> tuple[np.ndarray, float]:
    """``(_use_samples(e, S), pad)``: the pad is how far the use's p-curve may stray from its samples'
    polyline, its longest chord (0 for a straight p-curve, sampled by its two ends); both cached
    together, one look-up where both are (as :func:`_prefill_samples` leaves them)."""
    got = _USE_SAMPLES.get(e)
    if got is None or got[0] is not S:
        _use_samples(e, S)
        got = _USE_SAMPLES.get(e)
    if got[2] is None:
        Ue = got[1]
        pad = 0.0 if isinstance(e.pcurve, Line2D) else float(np.max(row_norms(np.diff(Ue, axis=0))))
        got = (S, Ue, pad)
        _USE_SAMPLES.set(e, got)
    return got[1], got[2]


#: Edge use -> (surface, its :func:`_edge_uv` samples on that surface, their pad (:func:`_use_samples_pad`) or None
#: until asked for).  By identity (one dict look-up, where a weak-key dictionary makes a weak
#: reference per look-up: a Boolean of a hundred tools reads a thousand uses twice).
_USE_SAMPLES = IdentityMemo()


def _loop_rings(spec: FaceSpec, n: int = _LOOP_SAMPLES, samples: list | None = None) -> list[np.ndarray]:
    """Each loop as a closed parameter-plane polyline ``(k, 2)`` (pole gaps closed by straight segments);
    ``samples``: :func:`_edge_samples` of ``spec`` when the caller has them."""
    return [np.concatenate(loop) for loop in (_edge_samples(spec, n) if samples is None else samples)]


class _FaceData:
    """Per-face data of a completed face spec that depends on nothing else (and the tolerance).

    ``loops`` the loops' :class:`_LoopData`, ``uv_box`` the enlarged parameter box, ``rings``
    (one per loop, :func:`_loop_rings`), ``seg (s, 2, 2)`` the rings' segments with their padded boxes
    ``seg_lo, seg_hi (s, 2)``, ``box (2, 3)`` the padded space box (:func:`_new_face_data`, None where
    none is proven) and ``edge_boxes`` (:meth:`_Operand.edge_boxes`, filled on demand); for
    phase 3's clipping, filled on demand: ``slope`` the segments' :func:`_polygon_slopes` and
    ``straight`` the closed-form clip's data (:func:`_straight_data`, False where it does not apply);
    ``loop_boxes`` (:func:`_loop_boxes`, on demand) each loop's first segment and the union of its
    segments' padded boxes.
    """

    __slots__ = ("t", "loops", "uv_box", "rings", "seg", "seg_lo", "seg_hi", "box", "edge_boxes", "slope",
                 "straight", "loop_boxes", "__weakref__")


#: Completed face spec -> its :class:`_FaceData`.  A spec is immutable (a frozen dataclass over
#: curves and surfaces that are values), so its data never goes stale; entries die with the spec.
_FACE_DATA: "weakref.WeakKeyDictionary[FaceSpec, _FaceData]" = weakref.WeakKeyDictionary()


def _forget_caches() -> None:
    """Forget everything coons remembers between operations: per-B-rep meshes and mass caches,
    what a Boolean result carries over (specs sewn, face and loop data, use samples and boxes,
    unmergeable pairs), what sewing, checking and mass properties remember per object, and the
    kernel's memos per curve and surface.

    For benchmarks that reuse their operands (a warm cache would time a reuse, not the
    operation) and for tests that compare a chain of Booleans warm and cold.  Results never
    depend on these caches, only the time does.
    """
    from coons.kernel import curve_intersect, intersect, onsurface
    from coons.topology import _memo, check, mass, sew, split, tessellate

    for cache in (tessellate._MESHES, mass._CACHE, check._SEWN_FROM, _FACE_DATA,
                  curve_intersect._TRIG, curve_intersect._FORMS, curve_intersect._MEMO, onsurface._PERIODS_CACHE,
                  split._FACES, split._MAPPED, intersect._COORDS):
        cache.clear()
    _memo.clear_all()  # every IdentityMemo and LastRecord (sewing, checking, mass, the pipeline's per-use memos)
    # The weak references to the last B-reps measured: with check._MEASURED cleared they can no longer
    # select a record, but a cold run should not hold them either.
    check._LAST_MEASURED[:] = [None] * len(check._LAST_MEASURED)


class _LoopData:
    """Per-loop parts of :class:`_FaceData`, cached per loop (:func:`_cached_loop`, :func:`_new_loop_data`).

    ``rest`` the loop's uses after the first, its key (identity-checked on every look-up; the
    first is not held, so that the entry dies with it), ``surface``, ``t``;
    ``ring (k, 2)`` (the uses' :func:`_use_samples` in turn), ``seg (k, 2, 2)`` and its padded
    boxes ``seg_lo, seg_hi``, the uses' :func:`_use_box_array` ``use_lo, use_hi (k, 3)`` (infinite
    where there is none); the loop's reductions are row ``row`` of ``table`` (:data:`_LOOP_COLUMNS`),
    the table of the :func:`_new_loop_data` pass that made it, so that a face's loops are gathered
    by index (:func:`_loop_rows`), not stacked row by row.
    """

    __slots__ = ("rest", "surface", "t", "ring", "seg", "seg_lo", "seg_hi", "use_lo", "use_hi", "table", "row")


#: The columns of a :class:`_LoopData`'s row: the ring's extremes ``rmin, rmax (2,)``, the union
#: ``seg_min, seg_max (2,)`` of its segments' padded boxes, the union ``box_lo, box_hi (3,)`` of its
#: uses' boxes (``nan`` when a use has none), the largest tolerance of its uses and 1 when a use
#: has no box (else 0).
_LOOP_COLUMNS = {"rmin": slice(0, 2), "rmax": slice(2, 4), "seg_min": slice(4, 6), "seg_max": slice(6, 8),
                 "box_lo": slice(8, 11), "box_hi": slice(11, 14), "tol": 14, "no_box": 15}


def _loop_rows(lds: list[_LoopData]) -> np.ndarray:
    """The rows ``(L, 16)`` of loops' data (:data:`_LOOP_COLUMNS`) in order, gathered from their tables
    (one gather for the loops of one :func:`_new_loop_data` pass: a hundred tools' faces)."""
    tables = list({id(ld.table): ld.table for ld in lds}.values())
    if len(tables) == 1:
        return tables[0][[ld.row for ld in lds]]
    at = dict(zip(map(id, tables), np.cumsum([0] + [len(T) for T in tables[:-1]]).tolist()))
    return np.concatenate(tables)[[at[id(ld.table)] + ld.row for ld in lds]]


#: First use of a loop -> its :class:`_LoopData`.  A face gaining a hole (a plate cut again and
#: again) keeps the very EdgeSpec objects, and so the loop data, of its other loops: its face
#: data costs one look-up per old loop plus the work on the new one.
_LOOP_DATA = IdentityMemo()


def _cached_loop(loop: list[EdgeSpec], S, t: Tolerance) -> _LoopData | None:
    """The cached :class:`_LoopData` of ``loop`` on ``S`` (the very same uses in order), else None."""
    ld = _LOOP_DATA.get(loop[0])
    if (ld is not None and ld.surface is S and ld.t == t and len(ld.rest) == len(loop) - 1
            and all(map(operator.is_, ld.rest, loop[1:]))):
        return ld
    return None


def _new_loop_data(items: list[tuple[list[EdgeSpec], object]], t: Tolerance) -> list[_LoopData]:
    """The :class:`_LoopData` of loops ``(loop, surface)``, computed together and cached.

    One array pass for all of them: the rings are the concatenated use samples, each loop's
    closing segment found by index, the extremes and boxes by ``reduceat`` over the loops (an
    operand of a hundred tools brings hundreds of new loops).  Each loop's arrays are read-only
    views of the pass's arrays; the values are those of one loop at a time.
    """
    uses = [e for loop, _ in items for e in loop]
    # (one look-up pass: _prefill_samples has left most uses' samples and pads; the rest by _use_samples_pad)
    surfaces = [S for loop, S in items for _ in loop]
    samples, pads = zip(*[got[1:] if got is not None and got[0] is S and got[2] is not None else _use_samples_pad(e, S)
                          for e, S, got in zip(uses, surfaces, _USE_SAMPLES.get_many(uses))])
    n_uses = np.array([len(loop) for loop, _ in items], dtype=np.int64)
    use_start = np.concatenate([[0], np.cumsum(n_uses)[:-1]])
    cnt = np.array([U.shape[0] for U in samples], dtype=np.int64)
    n_pts = np.add.reduceat(cnt, use_start)
    start = np.concatenate([[0], np.cumsum(n_pts)[:-1]])
    R = _frozen(np.concatenate(samples))
    nxt = np.arange(1, R.shape[0] + 1)
    nxt[start + n_pts - 1] = start  # each ring closes on its first sample
    seg = _frozen(np.stack([R, R[nxt]], axis=1))
    # A sampled curved edge stays within about one chord of its samples; a straight
    # p-curve (Line2D, sampled by its two ends) is its segment.
    pad = np.repeat(pads, cnt)[:, None]
    # (np.minimum of the two ends, not seg.min(axis=1): numpy reduces a short axis slowly)
    seg_lo = _frozen(np.minimum(R, R[nxt]) - pad)
    seg_hi = _frozen(np.maximum(R, R[nxt]) + pad)
    rmin = np.minimum.reduceat(R, start, axis=0)
    rmax = np.maximum.reduceat(R, start, axis=0)
    seg_min = np.minimum.reduceat(seg_lo, start, axis=0)
    seg_max = np.maximum.reduceat(seg_hi, start, axis=0)
    B, none = _use_box_array(uses)
    lo, hi = _frozen(B[:, 0].copy()), _frozen(B[:, 1].copy())
    box_lo = np.minimum.reduceat(lo, use_start, axis=0)
    box_hi = np.maximum.reduceat(hi, use_start, axis=0)
    no_box = np.logical_or.reduceat(none, use_start)
    tol = np.maximum.reduceat(np.array([e.tol or 0.0 for e in uses], dtype=np.float64), use_start)
    box_lo[no_box] = np.nan
    box_hi[no_box] = np.nan
    table = _frozen(np.concatenate([rmin, rmax, seg_min, seg_max, box_lo, box_hi, tol[:, None], no_box[:, None]],
                                   axis=1))
    out = []
    # (the bounds as Python ints, read once: a hundred tools bring hundreds of loops)
    bounds = zip(start.tolist(), (start + n_pts).tolist(), use_start.tolist(), (use_start + n_uses).tolist())
    for k, ((loop, S), (a, b, ua, ub)) in enumerate(zip(items, bounds)):
        ld = _LoopData()
        ld.rest, ld.surface, ld.t = tuple(loop[1:]), S, t
        ld.ring, ld.seg, ld.seg_lo, ld.seg_hi = R[a:b], seg[a:b], seg_lo[a:b], seg_hi[a:b]
        ld.use_lo, ld.use_hi = lo[ua:ub], hi[ua:ub]
        ld.table, ld.row = table, k
        out.append(ld)
    _LOOP_DATA.set_many([loop[0] for loop, _ in items], out)
    return out


def _face_data(spec: FaceSpec, t: Tolerance) -> _FaceData:
    """The :class:`_FaceData` of a completed spec (surface set, every use with a p-curve), cached
    per spec and assembled from its loops' :class:`_LoopData` (cached per loop)."""
    return _face_data_many([spec], t)[0]


def _face_data_many(specs: list[FaceSpec], t: Tolerance) -> list[_FaceData]:
    """:func:`_face_data` of many specs: the cached ones looked up, the rest computed together
    (:func:`_new_face_data`, their loop samples first in one pass, :func:`_prefill_samples`)."""
    data = [_FACE_DATA.get(spec) for spec in specs]
    fresh = [k for k, d in enumerate(data) if d is None or d.t != t]
    if fresh:
        # (a spec listed twice, as in both operands of a Boolean of a solid with itself, is computed once)
        todo = list({id(specs[k]): specs[k] for k in fresh}.values())
        # The kept data each face of many loops extends, found once for both passes (a plate's top
        # and bottom: the test compares every use of their hundred loops).
        kept = [_kept_prefix(spec, t) if len(spec.loops) > _PREFIX_LOOPS else None for spec in todo]
        _prefill_samples(todo, t, kept)
        made = {id(spec): d for spec, d in zip(todo, _new_face_data(todo, t, kept=kept))}
        for k in fresh:
            data[k] = made[id(specs[k])]
    return data


#: Loops from which a face's data is kept for a face that extends it by new loops, on a surface
#: without interior extremes (:func:`_extended_face_data`).
_PREFIX_LOOPS = 16
#: First use of a face's outer loop -> ``(the outer loop's other uses, the other loops' lengths,
#: their uses in order, t, the loops' :class:`_LoopData`, the per-face reductions of
#: :func:`_new_face_data`: rmin, rmax, seg_min, seg_max (2,), box lo, hi (3,), largest tolerance,
#: a box missing; the face's segments and their boxes seg, seg_lo, seg_hi)`` of the last face with
#: many loops computed on it: a plate's top gaining a hole every cut keeps its outer loop and its
#: other loops.  The value never holds the key (the outer loop is stored without it).
_FACE_PREFIX = IdentityMemo()


def _kept_prefix(spec: FaceSpec, t: Tolerance) -> tuple | None:
    """The entry of :data:`_FACE_PREFIX` whose loops are, use for use, the first loops of ``spec``
    (fewer than all of them) on its surface with ``t``, else None."""
    loops = spec.loops
    got = _FACE_PREFIX.get(loops[0][0]) if loops and loops[0] else None
    if got is None:
        return None
    rest0, lengths, uses, t_old, parts = got[:5]
    n = len(lengths) + 1
    # (the other loops' uses compared in one pass once their lengths agree: a plate's top has a hundred)
    if (t_old != t or n >= len(loops) or parts[0].surface is not spec.surface or len(loops[0]) != len(rest0) + 1
            or not all(map(operator.is_, rest0, loops[0][1:])) or tuple(map(len, loops[1:n])) != lengths
            or not all(map(operator.is_, uses, itertools.chain.from_iterable(loops[1:n])))):
        return None
    return got


def _extended_face_data(spec: FaceSpec, t: Tolerance, got: tuple | None = None) -> _FaceData | None:
    """The :class:`_FaceData` of ``spec`` from the kept data of a face whose loops are, use for
    use, the first loops of ``spec`` (:data:`_FACE_PREFIX`), and its new loops alone; None when
    there is no such face.

    Only on surfaces without interior extremes (planes, cylinders, cones: the space box is the
    union of the edge boxes).  Every per-face value of :func:`_new_face_data` is a minimum, a
    maximum or a concatenation over the loops in order, then one expression per face: combining
    the kept reductions with the new loops' gives the very same floats.  ``got``: the entry of
    :func:`_kept_prefix` when the caller has found it.
    """
    S = spec.surface
    loops = spec.loops
    got = _kept_prefix(spec, t) if got is None else got
    if got is None:
        return None
    parts, raw, kept_seg = got[4:]
    n = len(got[1]) + 1
    new = [(loop, _cached_loop(loop, S, t)) for loop in loops[n:]]
    todo = [(loop, S) for loop, ld in new if ld is None]
    made = iter(_new_loop_data(todo, t) if todo else [])
    new_parts = [next(made) if ld is None else ld for loop, ld in new]
    R, Rx, G, Gx, lo, hi, tol, no_box = raw
    V = _loop_rows(new_parts)
    c = _LOOP_COLUMNS
    R = np.minimum.reduce(np.concatenate([R[None], V[:, c["rmin"]]]))
    Rx = np.maximum.reduce(np.concatenate([Rx[None], V[:, c["rmax"]]]))
    G = np.minimum.reduce(np.concatenate([G[None], V[:, c["seg_min"]]]))
    Gx = np.maximum.reduce(np.concatenate([Gx[None], V[:, c["seg_max"]]]))
    no_box = no_box or bool(V[:, c["no_box"]].any())
    lo = np.minimum.reduce(np.concatenate([lo[None], V[:, c["box_lo"]]]))
    hi = np.maximum.reduce(np.concatenate([hi[None], V[:, c["box_hi"]]]))
    tol = max([tol] + V[:, c["tol"]].tolist())
    # (the kept face's segments, the concatenation of its loops' in order, joined with the new loops')
    seg = [np.concatenate([kept, *(getattr(ld, name) for ld in new_parts)]) for kept, name in
           zip(kept_seg, ("seg", "seg_lo", "seg_hi"))]
    return _face_data_from(spec, t, parts + new_parts, (R, Rx, G, Gx, lo, hi, tol, no_box), seg)


def _face_data_from(spec: FaceSpec, t: Tolerance, parts: list, raw: tuple, seg: list) -> _FaceData:
    """:class:`_FaceData` of ``spec`` on a surface without interior extremes from its loops' data,
    the per-face reductions ``raw`` (:data:`_FACE_PREFIX`) and its segments with their boxes ``seg``
    (``seg, seg_lo, seg_hi``: the loops' concatenated), as :func:`_new_face_data` makes it (the same
    expressions on one face's rows); cached, and kept for faces extending it."""
    R, Rx, G, Gx, lo, hi, tol, no_box = raw
    pad = tol + t.linear
    mu = _BOX_MARGIN * (Rx - R) + t.linear
    b0, b1, r0, r1 = (R - mu).tolist(), (Rx + mu).tolist(), R.tolist(), Rx.tolist()
    d = _FaceData()
    d.t, d.edge_boxes, d.slope, d.straight, d.loop_boxes = t, None, None, None, None
    d.loops = parts
    d.rings = [ld.ring for ld in parts]
    d.uv_box = _within_domain(spec.surface, (b0[0], b1[0]), (b0[1], b1[1]), (r0[1], r1[1]))
    d.seg, d.seg_lo, d.seg_hi = map(_frozen, seg)
    d.box = None if no_box else _frozen(np.stack([lo - pad, hi + pad]))
    _FACE_DATA[spec] = d
    _keep_prefix(spec, t, parts, raw, d)
    return d


def _keep_prefix(spec: FaceSpec, t: Tolerance, parts: list, raw: tuple, d: _FaceData) -> None:
    """Keep a face's loop data, reductions and segments (its :class:`_FaceData` ``d``) for the faces
    that extend it (:data:`_FACE_PREFIX`)."""
    loops = spec.loops
    if len(loops) >= _PREFIX_LOOPS and loops[0] and is_value(loops[0][0]):
        _FACE_PREFIX.set(loops[0][0], (tuple(loops[0][1:]), tuple(map(len, loops[1:])),
                                       tuple(itertools.chain.from_iterable(loops[1:])), t, list(parts), raw,
                                       (d.seg, d.seg_lo, d.seg_hi)))


def _new_face_data(specs: list[FaceSpec], t: Tolerance, extend: bool = True, kept: list | None = None
                   ) -> list[_FaceData]:
    """The :class:`_FaceData` of completed specs (each with a loop), computed together and cached
    (``extend``: first try :func:`_extended_face_data` on faces of many loops; ``kept``: per spec,
    its :func:`_kept_prefix` entry or None, when the caller has found them).

    The loops missing from the loop cache are computed in one :func:`_new_loop_data` pass; the
    parameter boxes and the space boxes of all faces are reductions over the stacked loop data
    (a hundred tools bring four hundred faces), with the expressions of one face at a time.

    The space box ``(2, 3)`` (rows ``lo, hi``) contains the face, padded by its edges'
    tolerances and ``t.linear``; it is None when an edge's curve has no proven box
    (:func:`_use_box_array`) or the surface's type is not handled (:func:`_interior_extremes`).
    Each coordinate ``x_k ∘ S`` is a smooth function of ``(u, v)`` on the face's parameter
    region ``D`` (compact), so its extremes lie on ``∂D`` or at interior critical points.  The
    image of ``∂D`` lies within the edge tolerances of the edge curves (``S(pcurve(t)) ≈
    curve(t)``; a gap at a pole maps to the vertex there), boxed by :func:`_use_box_array`.  The
    critical points add nothing on a plane (``x_k`` affine in ``(u, v)``), a cylinder or a cone
    (``x_k`` is affine along each ruling ``u = const``, so where its gradient vanishes it is
    constant along the whole ruling, which reaches ``∂D``); :func:`_interior_extremes` gives
    them for spheres and tori and bounds NURBS surfaces by their control points.
    """
    # A face extending a kept one by new loops (a plate's top gaining a hole) from the kept data.
    found, kept = kept, {}
    for k, spec in enumerate(specs if extend else ()):
        if len(spec.loops) > _PREFIX_LOOPS and _no_interior_extremes(spec.surface):
            got = _kept_prefix(spec, t) if found is None else found[k]
            if got is not None:
                kept[k] = got
    extended: dict[int, _FaceData] = {}
    if kept:
        # The loops without data, of those faces' new loops and of the other faces, in one
        # _new_loop_data pass (a plate's top and bottom gaining a hole, and the tool's faces),
        # which the assembly below then finds cached (each loop's data is that of the loop alone).
        todo: dict[tuple, tuple[list[EdgeSpec], object]] = {}
        for k, spec in enumerate(specs):
            S = spec.surface
            for loop in spec.loops[len(kept[k][1]) + 1 :] if k in kept else spec.loops:
                if _cached_loop(loop, S, t) is None:
                    todo.setdefault((id(S),) + tuple(map(id, loop)), (loop, S))
        if todo:
            _new_loop_data(list(todo.values()), t)
        for k, got in kept.items():
            d = _extended_face_data(specs[k], t, got)
            if d is not None:
                extended[k] = d
    if extended:
        rest = [spec for k, spec in enumerate(specs) if k not in extended]
        done = iter(_new_face_data(rest, t, extend=False) if rest else [])
        return [extended[k] if k in extended else next(done) for k in range(len(specs))]
    # A loop is its surface and every use (what _cached_loop checks), not its first use alone.
    todo: dict[tuple, tuple[list[EdgeSpec], object]] = {}
    parts_of = []
    missing: list[tuple[list, int, tuple]] = []  # (a face's parts, the loop's place, its key)
    for spec in specs:
        S = spec.surface
        parts = [_cached_loop(loop, S, t) for loop in spec.loops]
        for li, ld in enumerate(parts):
            if ld is None:
                loop = spec.loops[li]
                key = (id(S),) + tuple(map(id, loop))
                todo.setdefault(key, (loop, S))
                missing.append((parts, li, key))
        parts_of.append(parts)
    if todo:
        made = dict(zip(todo, _new_loop_data(list(todo.values()), t)))
        for parts, li, key in missing:
            parts[li] = made[key]
    V = _loop_rows([ld for parts in parts_of for ld in parts])
    c = _LOOP_COLUMNS
    first = np.cumsum([0] + [len(parts) for parts in parts_of[:-1]])
    # Per face: the rings' extremes (u0, v0, u1, v1), the segment boxes' union, the loop boxes'
    # union (nan when a loop has none) and the largest tolerance.
    R = np.minimum.reduceat(V[:, c["rmin"]], first, axis=0)
    Rx = np.maximum.reduceat(V[:, c["rmax"]], first, axis=0)
    G = np.minimum.reduceat(V[:, c["seg_min"]], first, axis=0)
    Gx = np.maximum.reduceat(V[:, c["seg_max"]], first, axis=0)
    no_box = np.logical_or.reduceat(V[:, c["no_box"]] != 0, first).tolist()
    lo = np.minimum.reduceat(V[:, c["box_lo"]], first, axis=0)
    hi = np.maximum.reduceat(V[:, c["box_hi"]], first, axis=0)
    tol_max = np.maximum.reduceat(V[:, c["tol"]], first)
    pad = tol_max + t.linear
    # Faces whose reductions are kept for faces extending them: no interior extremes to add.
    # (their rows of lo, hi are final here: only faces with interior extremes change theirs below)
    keep = [len(spec.loops) >= _PREFIX_LOOPS and _no_interior_extremes(spec.surface) for spec in specs]
    mu = _BOX_MARGIN * (Rx - R) + t.linear
    box_lo, box_hi = (R - mu).tolist(), (Rx + mu).tolist()
    uv_box = []
    for spec, b0, b1, r0, r1 in zip(specs, box_lo, box_hi, R.tolist(), Rx.tolist()):
        # (a plane or a cylinder: _within_domain leaves the box as it is, a hundred tools' faces without the call)
        uv_box.append(((b0[0], b1[0]), (b0[1], b1[1])) if type(spec.surface) in _WHOLE_DOMAIN
                      else _within_domain(spec.surface, (b0[0], b1[0]), (b0[1], b1[1]), (r0[1], r1[1])))
    # The parameter box that surely holds each face's region D: the segment boxes (padded by
    # the chords of curved p-curves) and the enlarged uv_box.
    U = np.array([(ub[0], vb[0], ub[1], vb[1]) for ub, vb in uv_box]).reshape(-1, 4)
    P_lo = np.minimum(U[:, :2], G).tolist()
    P_hi = np.maximum(U[:, 2:], Gx).tolist()
    for k, spec in enumerate(specs):
        if no_box[k]:
            continue
        S = spec.surface
        if _no_interior_extremes(S):
            continue  # (without the call)
        P = _interior_extremes(S, (P_lo[k][0], P_hi[k][0]), (P_lo[k][1], P_hi[k][1]))
        if P is None:
            no_box[k] = True
        elif P.shape[0]:
            lo[k], hi[k] = np.minimum(lo[k], P.min(axis=0)), np.maximum(hi[k], P.max(axis=0))
    boxes = _frozen(np.stack([lo - pad[:, None], hi + pad[:, None]], axis=1))
    out = []
    for k, (spec, parts) in enumerate(zip(specs, parts_of)):
        d = _FaceData()
        d.t, d.edge_boxes, d.slope, d.straight, d.loop_boxes = t, None, None, None, None
        d.loops = parts
        d.rings = [ld.ring for ld in parts]
        d.uv_box = uv_box[k]
        if len(parts) == 1:
            d.seg, d.seg_lo, d.seg_hi = parts[0].seg, parts[0].seg_lo, parts[0].seg_hi
        else:
            d.seg = _frozen(np.concatenate([ld.seg for ld in parts]))
            d.seg_lo = _frozen(np.concatenate([ld.seg_lo for ld in parts]))
            d.seg_hi = _frozen(np.concatenate([ld.seg_hi for ld in parts]))
        d.box = None if no_box[k] else boxes[k]
        _FACE_DATA[spec] = d
        out.append(d)
        if keep[k]:
            _keep_prefix(spec, t, parts, (R[k].copy(), Rx[k].copy(), G[k].copy(), Gx[k].copy(), lo[k].copy(),
                                          hi[k].copy(), float(tol_max[k]), no_box[k]), d)
    return out


#: Parameter slack of the critical-point tests of :func:`_interior_extremes`: many times the
#: rounding of ``atan2`` and ``hypot`` on angles up to a few π (a wider test only adds points).
_ANGLE_SLACK = 1e-12


def _no_interior_extremes(S) -> bool:
    """Whether no coordinate of ``S`` has a critical point inside a face (planes, cylinders, cones: a
    coordinate is affine along a ruling, see :func:`_new_face_data`)."""
    return isinstance(S, (PlanarSurface, CylindricalSurface, ConicalSurface))


def _interior_extremes(S, ub: tuple[float, float], vb: tuple[float, float]) -> np.ndarray | None:
    """Points ``(k, 3)`` of ``S`` whose box, joined with the box of the face's boundary, contains
    every point of ``S`` over a face whose parameter region lies in ``ub × vb``; None for a
    surface type not handled.

    Planes, cylinders, cones: none (see :func:`_new_face_data`).  Spheres and tori: the points where
    the outward normal is ``±e_k`` (``∇(x_k ∘ S) = 0`` there, ``S`` being an immersion), those of
    ``ub × vb`` (periodic directions shifted by whole periods), and the sphere's poles when
    ``vb`` reaches them (where ``Su = 0`` every ``x_k ∘ S`` may be critical).  With the frame
    column ``(a, b, c)`` of ``e_k`` and ``h = hypot(a, b)``, the normal ``cos v e(u) + sin v Z``
    is ``s e_k`` (``s = ±1``) at ``u = atan2(sσ b, sσ a)``, ``v = atan2(s c, σ h)``, ``σ = ±1``
    (only ``σ = 1`` on a sphere, whose ``v`` stays in ``[-π/2, π/2]``); when ``h = 0`` the critical
    set is the whole circle ``v = ±π/2``, where ``x_k`` does not depend on ``u``.  NURBS surfaces:
    the control points of the spans meeting ``ub × vb`` (the local convex hull property of
    NURBS surfaces, whose weights are positive; The NURBS Book §4.4).
    """
    from coons.kernel.analytic import SphericalSurface, ToroidalSurface
    from coons.kernel.surface import NurbsSurface

    if _no_interior_extremes(S):
        return np.zeros((0, 3))
    if isinstance(S, NurbsSurface):
        nu, nv = S.shape
        i0, i1 = _span_indices(S.knots_u, S.degree_u, nu, *ub)
        j0, j1 = _span_indices(S.knots_v, S.degree_v, nv, *vb)
        P = S.control_points[i0:i1, j0:j1].reshape(-1, S.dimension)
        return np.stack([P.min(axis=0), P.max(axis=0)])
    sphere = isinstance(S, SphericalSurface)
    if not sphere and not isinstance(S, ToroidalSurface):
        return None
    F = S.frame
    a, b, c = F[0], F[1], F[2]  # per coordinate k: e_k in the frame
    h = np.hypot(a, b)
    sig = (1.0,) if sphere else (1.0, -1.0)
    U, V, free_u = [], [], []
    for s in (1.0, -1.0):
        for sg in sig:
            U.append(np.arctan2(s * sg * b, s * sg * a))
            V.append(np.arctan2(s * c, sg * h))
            free_u.append(h == 0.0)
    U, V, free_u = np.concatenate(U), np.concatenate(V), np.concatenate(free_u)
    if sphere:
        U = np.append(U, [0.0, 0.0])
        V = np.append(V, [math.pi / 2, -math.pi / 2])
        free_u = np.append(free_u, [True, True])
    keep = (free_u | _in_periodic(U, ub)) & (_in_periodic(V, vb) if not sphere else
                                            (V >= vb[0] - _ANGLE_SLACK) & (V <= vb[1] + _ANGLE_SLACK))
    if not np.any(keep):
        return np.zeros((0, 3))
    return np.asarray(S.evaluate(U[keep], V[keep]), dtype=np.float64).reshape(-1, 3)


def _in_periodic(x: np.ndarray, box: tuple[float, float]) -> np.ndarray:
    """``(k,)`` bool: some ``x + 2π m`` lies in ``box`` widened by ``_ANGLE_SLACK``."""
    lo, hi = box[0] - _ANGLE_SLACK, box[1] + _ANGLE_SLACK
    first = x + 2.0 * math.pi * np.ceil((lo - x) / (2.0 * math.pi))  # the first shift at or above lo
    return first <= hi


def _span_indices(knots: np.ndarray, p: int, n: int, a: float, b: float) -> tuple[int, int]:
    """The control-point index slice ``[i0, i1)`` of the basis functions nonzero somewhere on
    ``[a, b]`` (knot spans of ``a`` and ``b`` clamped to the ``n`` control points' spans)."""
    sa = min(max(int(np.searchsorted(knots, a, side="right")) - 1, p), n - 1)
    sb = min(max(int(np.searchsorted(knots, b, side="right")) - 1, p), n - 1)
    return sa - p, sb + 1


# ---------------------------------------------------------------------- broad phase
def _broad_phase(A: _Operand, B: _Operand) -> tuple[np.ndarray, np.ndarray]:
    """The face pairs ``(I, J)`` of A and B whose closed space boxes share a point, sorted by ``I``
    then ``J``: :func:`~coons.booleans._broad_phase.box_pairs`, or for few pairs of faces the whole
    ``(F_A, F_B)`` overlap table (the same ``<=`` comparisons; :func:`numpy.nonzero` lists it in
    that order), which costs a few array operations where building two trees costs a few dozen
    (a box and a cylinder: six faces and three)."""
    if A.lo.shape[0] * B.lo.shape[0] <= _BROAD_TABLE:
        ov = None
        for k in range(3):  # (axis by axis: numpy reduces a short last axis slowly)
            o = (A.lo[:, None, k] <= B.hi[None, :, k]) & (B.lo[None, :, k] <= A.hi[:, None, k])
            ov = o if ov is None else ov & o
        I, J = np.nonzero(ov)
        return I.astype(np.int64, copy=False), J.astype(np.int64, copy=False)
    I, J = box_pairs(A.lo, A.hi, B.lo, B.hi)
    order = np.lexsort((J, I))
    return I[order], J[order]


#: Most face pairs :func:`_broad_phase` tests as one table (a few hundred kB of temporaries).
_BROAD_TABLE = 1 << 16


# ---------------------------------------------------------------------- intersect
class _Link:
    """A transversal stretch of an intersection branch inside both of its faces (phase 5's local test).

    The branch curve over ``[s0, s1]`` runs inside face ``faces[0]`` of A (with p-curve
    ``pcurves[0]``) and inside face ``faces[1]`` of B (``pcurves[1]``): a cut on both.
    """

    __slots__ = ("s0", "s1", "faces", "pcurves")

    def __init__(self, s0: float, s1: float, faces: tuple[int, int], pcurves: tuple) -> None:
        self.s0, self.s1, self.faces, self.pcurves = s0, s1, faces, pcurves


def _intersect(A: _Operand, B: _Operand, I: np.ndarray, J: np.ndarray, t: Tolerance,
               links: dict[int, list[_Link]] | None = None):
    """Cuts per face of A and of B: ``(dict face -> list of EdgeSpec, same for B)``.

    ``links`` (when given) receives, per branch curve object (``id``), the :class:`_Link` of
    every range that became a cut on both faces of its pair; a curve that repeats another
    cut of the same face (a branch along an edge of the other operand, found by both faces of
    that edge) has none: which face of the other operand it lies in is then ambiguous.

    Raises
    ------
    BooleanError
        (stage ``"intersect"``) a surface intersection or a clip failed; the pair is named.
    """
    from coons.kernel.intersect import intersect_surfaces

    cuts_a: dict[int, list[EdgeSpec]] = {}
    cuts_b: dict[int, list[EdgeSpec]] = {}
    bounded: set[int] = set()  # ids of the cuts whose ends _end_tolerance found on their face's boundary
    along: set[int] = set()  # ids of the cuts that run along the other operand's edges (_split_overlaps)
    sections = _batched_sections(A, B, I, J, t)
    try:
        ready, trusted = _batched_pieces(A, B, I, J, sections, t)
    except (CoonsError, ValueError, ArithmeticError) as exc:  # the loop below meets it again, naming the pair
        _log.debug("batched clips failed (%s: %s); per pair instead", type(exc).__name__, exc)
        ready, trusted = {}, False
    # The batched pieces' cuts by the trusted constructor when _batched_pieces vouches for their fields (a
    # hundred holes bring 800 cuts); the others by the validating one, which raises as before.
    edge_spec, trusted_spec = EdgeSpec, EdgeSpec._trusted
    for k, (i, j) in enumerate(zip(I.tolist(), J.tolist())):
        X, Y = A.specs[i], B.specs[j]
        try:
            curves = sections[k]
            if curves is None:
                si = intersect_surfaces(X.surface, Y.surface, A.uv_box[i], B.uv_box[j], t)
                if si.coincident:
                    for out, args in ((cuts_a.setdefault(i, []), (X, Y, A.uv_box[i])),
                                      (cuts_b.setdefault(j, []), (Y, X, B.uv_box[j]))):
                        k0 = len(out)
                        _imprint(*args, out, t)
                        along.update(id(e) for e in out[k0:])
                    continue
                curves = si.curves
            for c in curves:
                pieces = ready.get(id(c))
                make = edge_spec if pieces is None or not trusted else trusted_spec
                if pieces is None:
                    if c.tol > _REFIT_FACTOR * t.linear:
                        c = _refitted(c, X.surface, Y.surface, A.uv_box[i], B.uv_box[j], t)
                    pieces = _branch_pieces(A, B, i, j, c, t)
                for s0, s1, wa, wb, etol, near in pieces:
                    # Both ends within _check_cut_ends's reach of this face's boundary, for sure.
                    reach = 10.0 * max(t.linear, etol)
                    if wa == "inside":
                        cuts_a.setdefault(i, []).append(e := make(c.curve, s0, s1, c.pcurve_a, etol))
                        if max(near[0]) <= reach:
                            bounded.add(id(e))
                        if wb != "inside":
                            along.add(id(e))
                    if wb == "inside":
                        cuts_b.setdefault(j, []).append(e := make(c.curve, s0, s1, c.pcurve_b, etol))
                        if max(near[1]) <= reach:
                            bounded.add(id(e))
                        if wa != "inside":
                            along.add(id(e))
                    if wa == "inside" and wb == "inside" and links is not None:
                        links.setdefault(id(c.curve), []).append(_Link(s0, s1, (i, j), (c.pcurve_a, c.pcurve_b)))
        except BooleanError:
            raise
        except (CoonsError, ValueError, ArithmeticError) as exc:  # numpy's LinAlgError is a ValueError
            raise BooleanError(
                f"face {i} of A ({_kind(X)}) and face {j} of B ({_kind(Y)}): {type(exc).__name__}: {exc}",
                stage="intersect", diagnostics={"face_a": i, "face_b": j, "error": str(exc)},
            ) from exc
    repeated: set[int] = set()
    for X, cuts in ((A, cuts_a), (B, cuts_b)):
        resplit = _resplit_along(cuts, along, t)
        # (the quick test of the faces with few cuts, all in one pass: a hole's wall has two)
        few = [f for f, cs in cuts.items() if 2 <= len(cs) <= _SCALAR_CUTS and f not in resplit]
        apart = dict(zip(few, _apart_many([cuts[f] for f in few], t)))
        for f in list(cuts):
            cuts[f] = _unique_cuts(cuts[f], t, repeated, apart.get(f))
            if not cuts[f]:
                del cuts[f]
                continue
            if not all(id(c) in bounded for c in cuts[f]):
                _check_cut_ends(X, f, cuts[f], B if X is A else A, t)
    if links is not None:
        for key in repeated:
            links.pop(key, None)
    return cuts_a, cuts_b


#: Fewest plane–cylinder pairs that :func:`_batched_sections` takes together (fewer go pair by pair).
_BATCHED_SECTIONS = 2


def _batched_sections(A: _Operand, B: _Operand, I: np.ndarray, J: np.ndarray, t: Tolerance) -> list:
    """Per pair ``(I[k], J[k])``, its branches where a batched closed form covers it, else None.

    Pairs of a plane and a cylinder (either way round) go to
    :func:`~coons.kernel.intersect._plane_cylinder_circles` together (a plate's faces against
    the walls of many holes: one array pass instead of one closed form per pair); the pairs it
    does not cover, and all others, are left to :func:`~coons.kernel.intersect.intersect_surfaces`.

    When the batch raises (a degenerate circle or p-curve), every pair is left to the per-pair
    path, which reports the failing pair.
    """
    from coons.kernel.intersect import _plane_cylinder_circles

    out: list = [None] * len(I)
    if len(I) < _BATCHED_SECTIONS:
        return out
    pc = (PlanarSurface, CylindricalSurface)
    rows, items = [], []
    for k, (i, j) in enumerate(zip(I.tolist(), J.tolist())):
        Sa, Sb = A.specs[i].surface, B.specs[j].surface
        ta, tb = type(Sa), type(Sb)
        if ta is not tb and ta in pc and tb in pc:
            rows.append(k)
            items.append((Sa, Sb, A.uv_box[i], B.uv_box[j]))
    if len(rows) < _BATCHED_SECTIONS:
        return out
    try:
        found = _plane_cylinder_circles(items, t)
    except (CoonsError, ValueError, ArithmeticError) as exc:
        # The per-pair path runs instead, and names the pair that fails.
        _log.debug("batched plane-cylinder sections failed (%s: %s); per pair instead", type(exc).__name__, exc)
        return out
    for k, curves in zip(rows, found):
        out[k] = curves
    return out


def _branch_pieces(A: _Operand, B: _Operand, i: int, j: int, c, t: Tolerance) -> list[tuple]:
    """The cuts that branch ``c`` of face pair ``(i, j)`` makes: ``(s0, s1, where on A, where on B, end tolerance,
    near)`` per common sub-range of its clips to both faces that is long enough (``near``: per face, per end,
    the bound :func:`_end_tolerance` found on the end's distance to the face's boundary)."""
    ra = _clip(A, i, c.pcurve_a, c.t0, c.t1, t, c.curve)
    if not ra:
        return []
    rb = _clip(B, j, c.pcurve_b, c.t0, c.t1, t, c.curve)
    out = []
    for a0, a1, wa in ra:
        for b0, b1, wb in rb:
            s0, s1 = max(a0, b0), min(a1, b1)
            if s1 <= s0 or not _long_enough(c.curve, s0, s1, t):
                continue
            near = [[math.inf, math.inf], [math.inf, math.inf]]
            etol = _end_tolerance(c, (s0, s1), (A.edge_boxes(i), B.edge_boxes(j)), t, near)
            out.append((s0, s1, wa, wb, etol, near))
    return out


def _batched_pieces(A: _Operand, B: _Operand, I: np.ndarray, J: np.ndarray, sections: list,
                    t: Tolerance) -> tuple[dict, bool]:
    """``(id(branch) -> `` :func:`_branch_pieces` ``, trusted)`` of the batched sections' branches, in array
    passes: the clips (:func:`_clip_many` on each operand), the length test (:func:`_long_enough_many`) and the
    end tolerances (:func:`_end_tolerance_many`).  Branches whose deviation calls for :func:`_refitted` are
    left to the per-pair loop.  ``trusted``: every piece's range is two finite Python floats ``s0 < s1`` and
    its end tolerance a finite Python float ``>= 0`` (what ``EdgeSpec._trusted`` asks of its fields)."""
    rows = [(i, j, c) for (i, j), curves in zip(zip(I.tolist(), J.tolist()), sections) if curves
            for c in curves if c.tol <= _REFIT_FACTOR * t.linear]
    if not rows:
        return {}, False
    branches = [c for _, _, c in rows]
    ra = _clip_many(A, [i for i, _, _ in rows], [c.pcurve_a for c in branches], branches, t)
    on_a = [r for r, a in enumerate(ra) if a]  # (as the per-pair path: B is clipped only where A's clip is not empty)
    rb = dict(zip(on_a, _clip_many(B, [rows[r][1] for r in on_a], [branches[r].pcurve_b for r in on_a],
                                   [branches[r] for r in on_a], t))) if on_a else {}
    spans = []  # (row, s0, s1, where on A, where on B)
    for r in on_a:
        spans += [(r, max(a0, b0), min(a1, b1), wa, wb) for a0, a1, wa in ra[r] for b0, b1, wb in rb[r]
                  if min(a1, b1) > max(a0, b0)]
    out: dict = {id(c): [] for c in branches}
    if not spans:
        return out, False
    long = _long_enough_many([branches[r].curve for r, *_ in spans], [x[1] for x in spans], [x[2] for x in spans], t)
    spans = [x for x, ok in zip(spans, long) if ok]
    if not spans:
        return out, False
    ends = [(x[1], x[2]) for x in spans]
    etol, near = _end_tolerance_many([branches[r] for r, *_ in spans], ends,
                                     [(A, rows[r][0]) for r, *_ in spans], [(B, rows[r][1]) for r, *_ in spans], t)
    # (the ranges through one array: Python floats, the same values, whichever clip gave them; s0 < s1 above)
    ends_f = np.array(ends, dtype=np.float64)
    etol_f = np.array(etol, dtype=np.float64)
    trusted = bool(np.isfinite(ends_f).all() and np.isfinite(etol_f).all() and (etol_f >= 0.0).all())
    for (r, *_, wa, wb), (s0, s1), e, nr in zip(spans, ends_f.tolist(), etol, near):
        out[id(branches[r])].append((s0, s1, wa, wb, e, nr))
    return out, trusted


def _long_enough_many(curves: list, s0: list[float], s1: list[float], t: Tolerance) -> list[bool]:
    """:func:`_long_enough` of many ranges: circles in one array pass (the same five points,
    :func:`~coons.kernel.onsurface.curve_derivatives`), other curves one by one."""
    out = [None] * len(curves)
    rows = [k for k, c in enumerate(curves) if type(c) is Circle and math.isfinite(s0[k]) and math.isfinite(s1[k])]
    if rows:
        tt = linspace_rows([s0[k] for k in rows], [s1[k] for k in rows], 5)
        P = curve_derivatives([curves[k] for k in rows], tt, 0, 3)[:, :, 0]
        D = P - P[:, :1]
        far = np.sqrt(np.max(np.add.reduce(D * D, axis=2), axis=1)) > t.linear
        for k, ok in zip(rows, far.tolist()):
            out[k] = ok
    return [ok if ok is not None else _long_enough(c, a, b, t) for c, a, b, ok in zip(curves, s0, s1, out)]


def _end_tolerance_many(branches: list, ends: list[tuple[float, float]], face_a: list[tuple], face_b: list[tuple],
                        t: Tolerance) -> tuple[list[float], list[list[list[float]]]]:
    """:func:`_end_tolerance` (with ``near``) of many cut ranges, in array passes: ``(tolerances, nears)``.

    ``face_a[k], face_b[k]``: ``(operand, face)`` of the two faces of range ``k``.  The ends and their
    tangents of circle branches, every (range, face, edge) box test, and the distance and sine at edges on
    lines, in arrays; ends of other branches and edges on other curves by :func:`_end_tolerance`'s own
    per-range expressions (:func:`_end_sines`).
    """
    from coons.kernel.intersect import _curve_tangents

    M = len(branches)
    base = np.array([max(t.linear, c.tol) for c in branches])
    ts = np.array(ends, dtype=np.float64)  # (M, 2)
    P = np.empty((M, 2, 3))
    T = np.empty((M, 2, 3))
    circ = np.array([type(c.curve) is Circle and math.isfinite(a) and math.isfinite(b)
                     for c, (a, b) in zip(branches, ends)], dtype=bool)
    if circ.any():
        rows = np.flatnonzero(circ)
        D = curve_derivatives([branches[k].curve for k in rows.tolist()], ts[rows], 1, 3)
        P[rows], T[rows] = D[:, :, 0], D[:, :, 1]
    for k in np.flatnonzero(~circ).tolist():
        c, (a, b) = branches[k], ends[k]
        if math.isfinite(a) and math.isfinite(b):
            P[k], T[k] = _curve_tangents(c.curve, ts[k])
        else:
            D = np.asarray(c.curve.derivatives(ts[k], 1), dtype=np.float64)
            P[k], T[k] = D[:, 0], D[:, 1]
    T = T / np.maximum(np.sqrt(np.add.reduce(T * T, axis=2, keepdims=True)), 1e-300)
    size = 1.0 + np.abs(P).max(axis=(1, 2))
    # Every (range, side, edge) row, and the rows whose edge box comes near an end.  Many ranges share a face
    # (a plate's face meets every hole): each distinct face's edges are stacked once, and the rows index them.
    index: dict[tuple[int, int], int] = {}
    uniq: list[tuple] = []
    of = []
    for X, f in itertools.chain(face_a, face_b):
        u = index.get((id(X), f))
        if u is None:
            u = index[(id(X), f)] = len(uniq)
            uniq.append((X, f))
        of.append(u)
    # (the distinct faces' edge boxes made together, per operand; of a face of many loops not boxed yet, a
    # plate's face of a hundred holes, only the loops near its ranges' ends, :func:`_near_loop_edges`)
    of = np.array(of)
    local: dict[int, tuple] = {}
    for u, (X, f) in enumerate(uniq):
        if X._data[f].edge_boxes is None and len(X.specs[f].loops) > _LOOPS_BOXED:
            ks = np.flatnonzero(of == u) % M  # (the ranges on the face: row r is range r mod M's)
            local[u] = _near_loop_edges(X, f, P[ks].reshape(-1, 3), float(base[ks].max()))
    for X in {id(X): X for X, _ in uniq}.values():
        X.fill_edge_boxes([f for u, (Y, f) in enumerate(uniq) if Y is X and u not in local])
    uniq = [local[u] if u in local else X.edge_boxes(f) for u, (X, f) in enumerate(uniq)]
    edges_u = [e for edges, *_ in uniq for e in edges]
    n_u = np.array([len(edges) for edges, *_ in uniq])
    counts = n_u[of]
    total = int(counts.sum())
    # (row -> its edge among the stacked distinct faces' edges: the face's first edge, then along its edges)
    ge = np.repeat((np.cumsum(n_u) - n_u)[of] - (np.cumsum(counts) - counts), counts) + np.arange(total)
    lo = np.concatenate([elo for _, elo, _, _ in uniq])[ge]
    hi = np.concatenate([ehi for _, _, ehi, _ in uniq])[ge]
    etol = np.concatenate([tol for *_, tol in uniq])[ge]
    ent = np.repeat(np.tile(np.arange(M), 2), counts)
    side = np.repeat(np.arange(2), [int(counts[:M].sum()), int(counts[M:].sum())])
    reach = (10.0 * np.maximum(base[ent], etol))[:, None, None]
    Pe = P[ent]
    inb = (Pe >= lo[:, None] - reach) & (Pe <= hi[:, None] + reach)
    # (all over xyz and any over the two ends spelt out: numpy's reductions over such short axes are slow)
    inb = inb[..., 0] & inb[..., 1] & inb[..., 2]
    hit = inb[:, 0] | inb[:, 1]
    worst = base.copy()
    near = np.full((M, 2, 2), np.inf)
    rows = np.flatnonzero(hit)
    if rows.size:
        # (what the rows need of their edges, read once per distinct edge: a face's edge meets several ranges)
        hu, hinv = np.unique(ge[rows], return_inverse=True)
        E = [edges_u[g] for g in hu.tolist()]
        kinds = [type(e.curve) for e in E]
        line_u = np.array([kd is Line for kd in kinds], dtype=bool)
        line = line_u[hinv]
        delta = np.maximum(base[ent[rows]], np.array([e.tol or 0.0 for e in E])[hinv])
        d = np.empty((rows.size, 2))
        sine = np.empty((rows.size, 2))
        if line.any():
            lr = rows[line]
            le = [E[q] for q in np.flatnonzero(line_u).tolist()]
            at = (np.cumsum(line_u) - 1)[hinv[line]]  # (each line row's place among the distinct line edges)
            O = np.array([e.curve.origin for e in le])[at]
            D = np.array([e.curve.direction for e in le])[at]
            lo_t = np.array([min(e.t0, e.t1) for e in le])[at][:, None]
            hi_t = np.array([max(e.t0, e.t1) for e in le])[at][:, None]
            Q = P[ent[lr]]  # (n, 2, 3)
            te = np.clip(np.einsum("nej,nj->ne", Q - O[:, None], D), lo_t, hi_t)
            # (np.linalg.norm and np.cross written out: the same floats, see _local_tests)
            d[line] = row_norms(O[:, None] + te[..., None] * D[:, None] - Q)
            U = D / np.maximum(row_norms(D), 1e-300)[:, None]
            sine[line] = np.maximum(row_norms(_cross(T[ent[lr]], U[:, None])), _MIN_SINE)
        for q in np.flatnonzero(~line).tolist():
            e, k = E[hinv[q]], int(ent[rows[q]])
            dq, sq = _end_sines(e.curve, P[k], T[k], min(e.t0, e.t1), max(e.t0, e.t1), 10.0 * float(delta[q]), t)
            d[q], sine[q] = dq, sq
        on = d <= 10.0 * delta[:, None]
        ratio = np.where(on, delta[:, None] / sine, -np.inf)
        w = np.maximum(ratio[:, 0], ratio[:, 1])
        # As in _end_tolerance: a cut running along the edge (a circle of an earlier Boolean cut again by
        # the same plane) ends where another edge crosses it, and this one's tangent says nothing.
        for q in np.flatnonzero(w > 10.0 * delta).tolist():
            e = E[hinv[q]]
            if _runs_along(branches[int(ent[rows[q]])].curve, e.curve, min(e.t0, e.t1), max(e.t0, e.t1),
                           float(delta[q])):
                w[q] = -np.inf
        np.maximum.at(worst, ent[rows], w)
        known_u = np.array([kd in (Line, Circle, Ellipse) for kd in kinds], dtype=bool)
        known = known_u[hinv]
        if known.any():
            kr = rows[known]
            ke = [E[q] for q in np.flatnonzero(known_u).tolist()]
            O = np.abs(np.array([(e.curve.origin if type(e.curve) is Line else e.curve._origin) for e in ke]))
            O = np.maximum(np.maximum(O[:, 0], O[:, 1]), O[:, 2])[(np.cumsum(known_u) - 1)[hinv[known]]]
            slack = 1e-12 * (size[ent[kr]] + O)
            np.minimum.at(near, (ent[kr], side[kr]), d[known] + slack[:, None])
    return worst.tolist(), near.tolist()


def _near_loop_edges(X: _Operand, f: int, P: np.ndarray, base: float) -> tuple[list[EdgeSpec], np.ndarray,
                                                                              np.ndarray, np.ndarray]:
    """:meth:`_Operand.edge_boxes` of face ``f`` of X restricted to the loops whose box (the ``box_lo, box_hi``
    columns of :class:`_LoopData`'s row, the union of its uses' boxes) comes within :func:`_end_tolerance_many`'s reach of one of the points
    ``P (p, 3)`` (``base``: the largest tolerance of the ranges they end): ``(edges, lo, hi, tol)``.

    An edge's box lies in its loop's and its reach ``10 max(base, tol)`` is at most the loop's (its largest
    tolerance), so an end near no loop's box is near none of its edges' (a loop without a box is kept); the
    edges left out could not change the tolerances or the bounds found.
    """
    d, loops = X._data[f], X.specs[f].loops
    rows, c = _loop_rows(d.loops), _LOOP_COLUMNS
    no_box = rows[:, c["no_box"]] != 0.0
    keep = np.flatnonzero(no_box).tolist()
    boxed = np.flatnonzero(~no_box)
    if boxed.size:
        B_lo, B_hi = rows[boxed, c["box_lo"]], rows[boxed, c["box_hi"]]  # (n, 3) each
        R = 10.0 * np.maximum(base, rows[boxed, c["tol"]])
        hit = np.ones((P.shape[0], boxed.size), dtype=bool)
        for ax in range(3):  # (coordinate by coordinate: numpy reduces the short last axis row by row)
            hit &= (P[:, ax, None] >= B_lo[None, :, ax] - R) & (P[:, ax, None] <= B_hi[None, :, ax] + R)
        keep = sorted(keep + boxed[np.flatnonzero(hit.any(axis=0))].tolist())
    edges = [e for k in keep for e in loops[k]]
    if not keep:
        return edges, np.empty((0, 3)), np.empty((0, 3)), np.empty(0)
    return (edges, np.concatenate([d.loops[k].use_lo for k in keep]), np.concatenate([d.loops[k].use_hi for k in keep]),
            np.array([e.tol or 0.0 for e in edges], dtype=np.float64))


def _clip_many(X: _Operand, faces: list[int], pcurves: list, branches: list, t: Tolerance) -> list[list]:
    """:func:`_clip` of many branches ``branches[k]`` (``curve, t0, t1``) with p-curves ``pcurves[k]`` on faces
    ``faces[k]`` of X, in array passes over all of them.

    The same steps in the same order: the closed-form clip of a straight p-curve on a straight-sided face
    (:func:`_clip_straight_many`), then the sampled test of a ``Line2D`` or ``Trig2D`` p-curve that stays
    clear of its face's loops; the branches neither answers go through :func:`_clip` one by one.
    """
    n = len(faces)
    out: list = [None] * n
    _prefill_straight(X, list(dict.fromkeys(faces[k] for k in range(n) if type(pcurves[k]) is Line2D)), t)
    st = [k for k in range(n) if type(pcurves[k]) is Line2D and _straight_data(X, faces[k], t) is not None]
    if st:
        for k, r in zip(st, _clip_straight_many(X, [faces[k] for k in st], [pcurves[k] for k in st],
                                                 [branches[k] for k in st], t)):
            out[k] = r
    sm = [k for k in range(n) if out[k] is None and type(pcurves[k]) in (Line2D, Trig2D)
          and math.isfinite(branches[k].t0) and math.isfinite(branches[k].t1)]
    if sm:
        for k, r in zip(sm, _clear_many(X, [faces[k] for k in sm], [pcurves[k] for k in sm],
                                        [branches[k] for k in sm])):
            out[k] = r
    for k in range(n):
        if out[k] is None:
            c = branches[k]
            out[k] = _clip(X, faces[k], pcurves[k], c.t0, c.t1, t, c.curve)
    return out


def _clip_straight_many(X: _Operand, faces: list[int], pcurves: list, branches: list, t: Tolerance) -> list:
    """:func:`_clip_straight` of many ``Line2D`` p-curves on straight-sided faces (:func:`_straight_data` not None),
    in array passes: the sides of all faces padded to the most (padding sides have no length and meet
    nothing), the crossings and clearances by :func:`_straight_crossings_arrays`'s expressions, the pieces'
    midpoints against their faces by :func:`_in_faces`.  Per branch the clip, or None where it declines."""
    K = len(faces)
    # Each distinct face's sides once (a hole's wall meets the plate's top and bottom), scattered into its
    # padded row by (face, column) indices, then gathered per branch.
    index: dict[int, int] = {}
    inv = np.array([index.setdefault(f, len(index)) for f in faces], dtype=np.int64)
    data = [_straight_data(X, f, t) for f in index]
    m = np.array([len(d[3]) for d in data])
    width = int(m.max())
    at = np.repeat(np.arange(len(data)), m)
    col = np.arange(at.size) - np.repeat(np.cumsum(m) - m, m)
    A = np.zeros((len(data), width, 2))
    E = np.zeros((len(data), width, 2))
    L = np.zeros((len(data), width))
    valid = np.zeros((len(data), width), dtype=bool)
    A[at, col] = np.concatenate([d[1] for d in data])
    E[at, col] = np.concatenate([d[2] for d in data])
    L[at, col] = np.concatenate([d[3] for d in data])
    valid[at, col] = True
    A, E, L, valid = A[inv], E[inv], L[inv], valid[inv]
    sp = np.array([d[0] for d in data])[inv]
    largest = np.array([d[6] for d in data])[inv]
    o = np.array([p.origin for p in pcurves])
    dd = np.array([p.direction for p in pcurves])
    t0 = np.array([c.t0 for c in branches])
    t1 = np.array([c.t1 for c in branches])
    lo_t, hi_t = np.minimum(t0, t1), np.maximum(t0, t1)
    p0, d = o * sp, dd * sp
    Bk = np.stack([p0 + lo_t[:, None] * d, p0 + hi_t[:, None] * d], axis=1)  # (K, 2, 2) the branches' ends
    scale = 1.0 + np.maximum(largest, np.abs(Bk).max(axis=(1, 2)))
    margin = (_STRAIGHT_CLEARANCE * t.linear + 1e-12 * scale)[:, None]
    dn = np.hypot(d[:, 0], d[:, 1])[:, None]
    d0, d1 = d[:, 0:1], d[:, 1:2]
    W = A - p0[:, None]
    cross = d0 * E[..., 1] - d1 * E[..., 0]
    lo, hi = lo_t[:, None], hi_t[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        sc = (W[..., 0] * E[..., 1] - W[..., 1] * E[..., 0]) / cross  # branch parameter of the crossing
        w = (W[..., 0] * d1 - W[..., 1] * d0) / cross  # fraction along the side
        meets = valid & (cross != 0.0) & (w >= 0.0) & (w <= 1.0) & (sc >= lo) & (sc <= hi)
        crossing = meets & (np.abs(cross) >= _STRAIGHT_MIN_SINE * dn * L) & (w * L > margin) \
            & ((1.0 - w) * L > margin) & ((sc - lo) * dn > margin) & ((hi - sc) * dn > margin)
    # Clearance (_straight_clearance_arrays): the sides' ends from the branch, the branch's ends from the sides.
    V = np.concatenate([A, A + E], axis=1)
    tv = np.clip(np.einsum("kvj,kj->kv", V - p0[:, None], d) / (dn * dn), lo, hi)
    near = np.hypot(*np.moveaxis(V - p0[:, None] - tv[..., None] * d[:, None], 2, 0))
    near = np.where(np.concatenate([valid, valid], axis=1), near, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        fb = np.clip(np.einsum("kbsj,ksj->kbs", Bk[:, :, None] - A[:, None], E) / (L * L)[:, None], 0.0, 1.0)
    Fb = Bk[:, :, None] - A[:, None] - fb[..., None] * E[:, None]
    far = np.where(valid[:, None], np.hypot(Fb[..., 0], Fb[..., 1]), np.inf)
    clearance = np.minimum(near.min(axis=1), far.min(axis=(1, 2)))
    ok = ~np.any(meets & ~crossing, axis=1) & (clearance > margin[:, 0])
    out: list = [None] * K
    # Each branch's break points in one (K, width + 2) array: its lower end, its crossings in order, its upper
    # end, then padding (inf); piece j runs from column j to j + 1 and is real for j < crossings + 1.
    ncross = np.count_nonzero(crossing, axis=1)
    br = np.full((K, width + 2), np.inf)
    br[:, 0] = lo_t
    br[:, 1 : width + 1] = np.sort(np.where(crossing, sc, np.inf), axis=1)
    br[np.arange(K), ncross + 1] = hi_t
    real = np.arange(width + 1)[None] <= ncross[:, None]
    a, b = br[:, :-1], br[:, 1:]
    with np.errstate(invalid="ignore"):  # (padding: inf - inf)
        short = real & ((b - a) * dn <= margin)
    # (two crossings at one place: a vertex, let the general path decide)
    ok &= ~short.any(axis=1)
    if not ok.any():
        return out
    own, col = np.nonzero(real & ok[:, None])  # the pieces, branch by branch in order
    a, b = a[own, col], b[own, col]
    inside = _in_faces(X, np.array(faces)[own], o[own] + (0.5 * (a + b))[:, None] * dd[own])
    # Runs of consecutive inside pieces of one branch, by their first and last piece.
    first = col == 0
    last = np.append(own[1:] != own[:-1], True)
    prev_in = np.append(False, inside[:-1]) & ~first
    next_in = np.append(inside[1:], False) & ~last
    starts = np.flatnonzero(inside & ~prev_in)
    ends = np.flatnonzero(inside & ~next_in)
    runs: dict[int, list] = {k: [] for k in np.flatnonzero(ok).tolist()}
    for k, s0, s1 in zip(own[starts].tolist(), a[starts].tolist(), b[ends].tolist()):
        runs[k].append((s0, s1, "inside"))
    for k, res in runs.items():
        S = X.specs[faces[k]].surface
        if not res and (getattr(S, "periodic_u", False) or getattr(S, "periodic_v", False)):
            continue  # (as in _clip_straight: a period away is the general path's business)
        if t0[k] > t1[k]:
            res = [(s1, s0, w_) for s0, s1, w_ in reversed(res)]
        out[k] = res
    return out


def _clear_many(X: _Operand, faces: list[int], pcurves: list, branches: list) -> list:
    """The sampled test of :func:`_clip` for many branches: ``[(t0, t1, "inside")]``, ``[]`` or None (undecided)."""
    T = linspace_rows([c.t0 for c in branches], [c.t1 for c in branches], _CLEAR_SAMPLES)
    Q = curve_derivatives(pcurves, T, 0, 2)[:, :, 0]
    finite = np.isfinite(Q).all(axis=(1, 2))  # (as _clip: non-finite samples leave the branch undecided)
    if not finite.all():
        Q = np.where(finite[:, None, None], Q, 0.0)
    # (the largest step's root as the largest root, and the extremes per coordinate: the same floats, without
    # numpy's row-by-row reductions of a short axis)
    step = np.max(row_norms(Q[:, 1:] - Q[:, :-1]), axis=1)[:, None]
    scale = 1.0 + np.max(np.abs(Q), axis=(1, 2))[:, None]
    Q_lo, Q_hi = _middle_extremes(Q)
    lo = Q_lo - step - 1e-9 * scale  # rounding margin of parameter values
    hi = Q_hi + step + 1e-9 * scale
    fa = np.array(faces)
    meet = np.zeros(len(faces), dtype=bool)
    for f in np.unique(fa).tolist():
        rows = np.flatnonzero(fa == f)
        # Only the segments of the loops whose box meets a branch's (a plate's face of a hundred holes: a
        # segment box meets a branch's only inside its loop's box, so the others cannot change the answer).
        seg = _near_loop_segments(X._data[f], X.specs[f], lo[rows], hi[rows])
        s_lo, s_hi = X.seg_lo[f][seg], X.seg_hi[f][seg]
        meet[rows] = np.any(np.all((s_lo[None] <= hi[rows, None]) & (s_hi[None] >= lo[rows, None]), axis=2), axis=1)
    out: list = [None] * len(faces)
    clear = np.flatnonzero(~meet & finite)
    if clear.size:
        inside = _in_faces(X, fa[clear], Q[clear, _CLEAR_SAMPLES // 2])
        for k, ins in zip(clear.tolist(), inside.tolist()):
            S = X.specs[faces[k]].surface
            if ins:
                out[k] = [(branches[k].t0, branches[k].t1, "inside")]
            elif not (getattr(S, "periodic_u", False) or getattr(S, "periodic_v", False)):
                out[k] = []
    return out


def _near_loop_segments(d: "_FaceData", spec: FaceSpec, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | slice:
    """The rows of ``d.seg`` (the data of face ``spec``) on the loops whose padded box (:func:`_loop_boxes`)
    meets one of the closed boxes ``lo, hi (n, 2)``; every row (a slice) for a face of at most
    :data:`_LOOPS_BOXED` loops.

    A segment's padded box lies in its loop's, so a box that meets no loop's meets none of its segments'."""
    if len(d.loops) <= _LOOPS_BOXED:
        return slice(None)
    first, llo, lhi = _loop_boxes(d, spec)
    hit = np.ones((lo.shape[0], llo.shape[0]), dtype=bool)
    for ax in (0, 1):  # (coordinate by coordinate: numpy reduces the short last axis row by row)
        hit &= (llo[None, :, ax] <= hi[:, ax, None]) & (lhi[None, :, ax] >= lo[:, ax, None])
    return _loop_segment_rows(first, d.seg_lo.shape[0], np.flatnonzero(hit.any(axis=0)))


def _loop_segment_rows(first: np.ndarray, total: int, loops: np.ndarray) -> np.ndarray:
    """The rows, in order, of the segments of the loops ``loops`` (ascending) of a face whose loops' segments
    start at rows ``first`` of its ``total``: one range per loop."""
    count = np.append(first, total)[loops + 1] - first[loops]
    return np.repeat(first[loops] - (np.cumsum(count) - count), count) + np.arange(int(count.sum()))


#: Faces of at most this many polygon segments are tested together by :func:`_in_faces`, padded to the
#: largest; larger ones one face at a time.
_PAD_SEGMENTS = 256


def _in_faces(X: _Operand, faces: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """:func:`~coons.booleans.classify._in_polygon` of points ``Q (m, 2)``, each against its face ``faces[m]`` of X
    (the same crossings and comparisons; padding segments straddle no line)."""
    from coons.booleans.classify import _in_polygon, _polygon_slopes

    out = np.zeros(len(Q), dtype=bool)
    uniq, inv = np.unique(faces, return_inverse=True)
    sizes = [len(X.segments[f]) for f in uniq.tolist()]
    small = [u for u, n in enumerate(sizes) if 0 < n <= _PAD_SEGMENTS]
    for u, n in enumerate(sizes):
        if n > _PAD_SEGMENTS:
            rows = np.flatnonzero(inv == u)
            f = int(uniq[u])
            # Only the loops whose box spans a point's height: a segment straddles the line y = const only
            # within its loop's box, so the others add no crossing (a plate's face of a hundred holes).
            y = Q[rows, 1:2]
            seg = _near_loop_segments(X._data[f], X.specs[f], np.concatenate([np.full_like(y, -np.inf), y], axis=1),
                                      np.concatenate([np.full_like(y, np.inf), y], axis=1))
            # (the near loops' slopes by _in_polygon itself, the same divisions: the whole face's are not needed)
            out[rows] = _in_polygon(Q[rows], X.segments[f][seg], _slopes(X, f) if type(seg) is slice else None)
    if small:
        width = max(sizes[u] for u in small)
        pad = np.full((len(uniq), 4, width), np.nan)  # rows: start x, start y, end y, slope
        # All small faces' segments in one array, scattered into the pad by (face, column) indices; their
        # slopes in one elementwise pass (the same divisions as _slopes per face, so the same values).
        seg = np.concatenate([X.segments[f] for f in uniq[small].tolist()])
        n = np.array([sizes[u] for u in small])
        at = np.repeat(np.asarray(small), n)
        col = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
        pad[at, 0, col], pad[at, 1, col], pad[at, 2, col] = seg[:, 0, 0], seg[:, 0, 1], seg[:, 1, 1]
        pad[at, 3, col] = _polygon_slopes(seg)
        rows = np.arange(len(Q)) if len(small) == len(sizes) else np.flatnonzero(np.isin(inv, small))
        ax, ay, cy, m = np.moveaxis(pad[inv[rows]], 1, 0)
        x, y = Q[rows, 0:1], Q[rows, 1:2]
        with np.errstate(invalid="ignore"):
            hit = ((ay > y) != (cy > y)) & (x < ax + (y - ay) * m)
        out[rows] = np.count_nonzero(hit, axis=1) % 2 == 1
    return out


#: A branch whose recorded deviation exceeds this many ``tol.linear`` gets its p-curves rebuilt
#: from its 3-D curve (the intersector promises fitted p-curves within ``tol.linear``; far above
#: it a fit has gone wrong, e.g. across a sphere pole, while the 3-D curve is usually exact).
_REFIT_FACTOR = 10.0


def _refitted(c, Sa, Sb, box_a, box_b, t: Tolerance):
    """Branch ``c`` with a p-curve far from its 3-D curve recomputed from it by ``pcurve_on``.

    Each p-curve's deviation is measured on :data:`_REFIT_SAMPLES` parameters; only one that
    exceeds ``_REFIT_FACTOR · tol.linear`` is rebuilt (``pcurve_on`` also verifies that the 3-D
    curve lies on the surface within ``tol.linear``).  When the rebuild fails or does not
    deviate less, the old p-curve stays (its large tolerance then shows downstream).
    """
    from dataclasses import replace

    from coons.kernel.onsurface import pcurve_on

    tt = np.linspace(c.t0, c.t1, _REFIT_SAMPLES)
    P = np.asarray(c.curve.evaluate(tt), dtype=np.float64)
    new, devs = {}, []
    for key, S, box in (("pcurve_a", Sa, box_a), ("pcurve_b", Sb, box_b)):
        pc = getattr(c, key)
        uv = np.asarray(pc.evaluate(tt), dtype=np.float64)
        dev = float(np.max(np.linalg.norm(np.asarray(S.evaluate(uv[:, 0], uv[:, 1])).reshape(-1, 3) - P, axis=1)))
        if dev > _REFIT_FACTOR * t.linear:
            try:
                pc2, dev2 = pcurve_on(S, c.curve, c.t0, c.t1, box=box, tol=t)
            except CoonsError as exc:
                _log.debug("p-curve deviating %.3g kept: it cannot be rebuilt (%s)", dev, exc)
            else:
                if dev2 < dev:
                    new[key], dev = pc2, dev2
        devs.append(dev)
    if not new:
        return c
    _log.debug("branch p-curves %s rebuilt from its 3-D curve: deviation %.3g -> %.3g", sorted(new), c.tol, max(devs))
    return replace(c, tol=max(max(devs), t.linear), **new)


#: Samples on which a suspicious branch's p-curves are measured against its 3-D curve.
_REFIT_SAMPLES = 129


#: Samples of a branch's p-curve for the quick test that it stays clear of a face's boundary.
_CLEAR_SAMPLES = 33


def _clip(X: _Operand, f: int, pcurve, t0: float, t1: float, t: Tolerance, curve) -> list[tuple[float, float, str]]:
    """``clip_to_face`` of face ``f`` of X, answered at once when the branch stays clear of the face's loops.

    The p-curve is sampled; when the box of the samples (enlarged by the largest sample step)
    meets no box of a loop segment (enlarged by its length, see ``_Operand``), the branch
    neither crosses nor touches the boundary, and one sample inside or outside the trim polygon
    decides the whole range.  Otherwise (near the boundary) a straight p-curve on a face bounded
    by straight p-curves is clipped in closed form (:func:`_clip_straight`) when it crosses the
    boundary properly, and else the exact ``clip_to_face`` runs.

    A straight p-curve on a face that :func:`_clip_straight` takes goes there first: where the
    sampled test would answer, the branch meets no side and stays clear of the polygon, so the
    closed form finds no crossing and classifies one point of the same branch, which gives the
    same answer (or declines, and the sampled test answers).
    """
    from coons.booleans.classify import _in_polygon
    from coons.topology.split import clip_to_face

    straight = _clip_straight(X, f, pcurve, t0, t1, t)
    if straight is not None:
        return straight
    Q = None
    if pcurve is not None and math.isfinite(t0) and math.isfinite(t1):
        # (evaluate's expressions; a polynomial NURBS, the fits of intersection branches, by scipy's
        # B-spline, kernel.curve.spline_points: round-off, far inside the margins below, which decide
        # only whether the quick answer is taken, never a crossing)
        try:
            Q = np.asarray(_pcurve_points(pcurve, np.linspace(t0, t1, _CLEAR_SAMPLES)), dtype=np.float64)
        except (CoonsError, ValueError, TypeError, ArithmeticError):
            Q = None
    if Q is not None and Q.shape == (_CLEAR_SAMPLES, 2) and np.all(np.isfinite(Q)):
        # The largest step: the root of the largest squared step (the norms' own sums; sqrt is
        # monotone and correctly rounded, so this is the largest norm).
        dQ = Q[1:] - Q[:-1]
        step = math.sqrt(float(np.max(np.add.reduce(dQ * dQ, axis=1))))
        scale = 1.0 + float(np.max(np.abs(Q)))
        lo = Q.min(axis=0) - step - 1e-9 * scale  # rounding margin of parameter values
        hi = Q.max(axis=0) + step + 1e-9 * scale
        meet = np.all((X.seg_lo[f] <= hi) & (X.seg_hi[f] >= lo), axis=1)
        if not np.any(meet):
            inside = bool(_in_polygon(Q[_CLEAR_SAMPLES // 2][None], X.segments[f], _slopes(X, f))[0])
            if inside:
                return [(t0, t1, "inside")]
            S = X.specs[f].surface
            if not (getattr(S, "periodic_u", False) or getattr(S, "periodic_v", False)):
                return []  # (on a periodic surface clip_to_face may still find it a period away)
    return clip_to_face(X.specs[f], pcurve, t0, t1, t, curve=curve)


def _slopes(X: _Operand, f: int) -> np.ndarray:
    """:func:`~coons.booleans.classify._polygon_slopes` of face ``f``'s segments, computed once per face spec."""
    d = X._data[f]
    if d.slope is None:
        from coons.booleans.classify import _polygon_slopes

        d.slope = _frozen(_polygon_slopes(d.seg))
    return d.slope


#: A straight branch is clipped in closed form (:func:`_clip_straight`) only when every feature of
#: the face's polygon is farther than this many tolerances from it, or crosses it properly:
#: ``clip_to_face`` merges and refines what lies within one tolerance, so far outside that band
#: both compute the same crossings (up to round-off) and the same inside/outside pieces.
_STRAIGHT_CLEARANCE = 100.0
#: Smallest sine of the angle at which a straight branch may cross a polygon side in the closed-form
#: clip: at a grazing crossing a tolerance-sized error moves the crossing far along both lines, and
#: ``clip_to_face`` re-solves it in space; such branches take that path.
_STRAIGHT_MIN_SINE = 1e-2


def _straight_data(X: _Operand, f: int, t: Tolerance) -> tuple | None:
    """What :func:`_clip_straight` needs of face ``f`` alone, computed once per face spec; None when the face
    does not qualify (not a plane or cylinder, or an edge use without a ``Line2D`` p-curve or with a
    tolerance above ``tol.linear``, or no polygon side of positive length).

    ``(speed (2,), A (k, 2), E (k, 2), L (k,), L², V (2k, 2), largest |A|, sides, size)``: the
    sides' starts, vectors and lengths in the isometric coordinates (zero-length sides dropped),
    their starts and ends, the largest start coordinate before the drop (as the clip's scale
    takes it), the sides as tuples ``(A_k, E_k, L_k, L_k²)`` of Python floats and ``1 + max |V|``.
    """
    d = X._data[f]
    if d.straight is None:
        _prefill_straight(X, [f], t)
    return d.straight or None


def _prefill_straight(X: _Operand, faces: list[int], t: Tolerance) -> None:
    """:func:`_straight_data` of the faces ``faces`` of X not computed yet, in one array pass over
    their segments (the walls of a hundred holes): the sides of each face are rows of the
    stacked arrays (read-only views), reduced per face."""
    todo, speeds = [], []
    for f in faces:
        d = X._data[f]
        if d.straight is not None:
            continue
        spec = X.specs[f]
        S = spec.surface
        if isinstance(S, PlanarSurface):
            speed = (1.0, 1.0)
        elif isinstance(S, CylindricalSurface):
            speed = (float(S.radius), 1.0)
        else:
            d.straight = False
            continue
        if any(not isinstance(e.pcurve, Line2D) or (e.tol or 0.0) > t.linear for loop in spec.loops for e in loop):
            d.straight = False
            continue
        todo.append(f)
        speeds.append(speed)
    if not todo:
        return
    counts = [X._data[f].seg.shape[0] for f in todo]
    first = np.cumsum([0] + counts[:-1])
    seg = np.concatenate([X._data[f].seg for f in todo])
    sp_f = np.array(speeds)
    sp = np.repeat(sp_f, counts, axis=0)
    A = seg[:, 0] * sp
    E = seg[:, 1] * sp - A
    absA, absV = np.abs(A), np.abs(A + E)
    largest = np.maximum.reduceat(np.maximum(absA[:, 0], absA[:, 1]), first).tolist()
    L = np.hypot(E[:, 0], E[:, 1])
    side = L > 0.0  # a closed loop repeats each vertex as a zero-length segment: it is a vertex
    LL = L * L
    VA = np.where(side, np.maximum(np.maximum(absA[:, 0], absA[:, 1]), np.maximum(absV[:, 0], absV[:, 1])), -np.inf)
    vmax = np.maximum.reduceat(VA, first).tolist()
    # The sides kept, of all faces: face k's are rows kept[k] : kept[k + 1].
    A, E, L, LL = A[side], E[side], L[side], LL[side]
    AE = A + E
    for x in (sp_f, A, E, L, LL):  # (each face's arrays are read-only views of these)
        _frozen(x)
    n_kept = np.add.reduceat(side.astype(np.int64), first)
    at = np.cumsum(n_kept) - n_kept
    # Each face's side starts then ends, V (its rows 2 a : 2 b), for all faces in one array: row r of face k
    # (rows a : b) goes to r + a, its end to r + a + (b - a).
    own = np.repeat(at, n_kept)
    V = np.empty((2 * A.shape[0], 2))
    V[np.arange(A.shape[0]) + own] = A
    V[np.arange(A.shape[0]) + own + np.repeat(n_kept, n_kept)] = AE
    _frozen(V)
    kept = np.append(at, A.shape[0]).tolist()
    sides = list(zip(A.tolist(), E.tolist(), L.tolist(), LL.tolist()))
    for k, f in enumerate(todo):
        a, b = kept[k], kept[k + 1]
        d = X._data[f]
        if a == b:
            d.straight = False
            continue
        d.straight = (sp_f[k], A[a:b], E[a:b], L[a:b], LL[a:b], V[2 * a : 2 * b], largest[k], sides[a:b], 1.0 + vmax[k])


#: Up to this many polygon sides :func:`_clip_straight` tests them in Python floats.
_SCALAR_SIDES = 16
#: :func:`_straight_crossings` found a clearance it cannot tell from the margin.
_UNDECIDED = object()


def _straight_crossings_arrays(A, E, L, LL, V, p0, d, B, lo_t, hi_t, dn: float, margin: float) -> list[float] | None:
    """The branch parameters where it crosses the sides properly, or None (see :func:`_clip_straight`)."""
    d0, d1 = d.tolist()
    W = A - p0
    cross = d0 * E[:, 1] - d1 * E[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (W[:, 0] * E[:, 1] - W[:, 1] * E[:, 0]) / cross  # branch parameter of the crossing
        w = (W[:, 0] * d1 - W[:, 1] * d0) / cross  # fraction along the side
        meets = (cross != 0.0) & (w >= 0.0) & (w <= 1.0) & (s >= lo_t) & (s <= hi_t)
    crossing = meets & (np.abs(cross) >= _STRAIGHT_MIN_SINE * dn * L) & (w * L > margin) \
        & ((1.0 - w) * L > margin) & ((s - lo_t) * dn > margin) & ((hi_t - s) * dn > margin)
    # Every other side must not meet the branch at all (a grazing crossing, or one near an end).
    # Then the distance between it and the branch is the least of the four end-to-segment
    # distances (where round-off puts a meeting just outside a segment, it lies near an end and
    # that distance is small): every polygon vertex must stay clear of the branch, and the
    # branch's ends clear of every side (of crossing sides too: declining more is safe).
    if np.any(meets & ~crossing):
        return None
    if _straight_clearance_arrays(A, E, LL, V, p0, d, B, lo_t, hi_t, dn) <= margin:
        return None
    return s[crossing].tolist()


def _straight_clearance_arrays(A, E, LL, V, p0, d, B, lo_t, hi_t, dn: float) -> float:
    """The least distance between the polygon's vertices and the branch and between its ends and the sides."""
    tv = np.clip(((V - p0) @ d) / (dn * dn), lo_t, hi_t)
    near = np.hypot(*(V - p0 - tv[:, None] * d).T)
    fb = np.clip(np.einsum("bkj,kj->bk", B[:, None, :] - A[None], E) / LL, 0.0, 1.0)  # (2, k)
    Fb = B[:, None, :] - A[None] - fb[..., None] * E[None]
    return min(float(np.min(near)), float(np.min(np.hypot(Fb[..., 0], Fb[..., 1]))))


def _straight_crossings(sides, p0, d, B, lo_t: float, hi_t: float, dn: float, margin: float, size: float):
    """:func:`_straight_crossings_arrays` of a few sides in Python floats: the crossings and the tests on
    them by the same expressions, element by element; the clearance (numpy's matrix product and
    ``hypot`` round their own way) to within ``1e-12 size``, far above the round-off of either:
    :data:`_UNDECIDED` where it lies that close to the margin."""
    (p00, p01), (d0, d1) = p0, d
    found = []
    for (a0, a1), (e0, e1), length, _ in sides:
        w0, w1 = a0 - p00, a1 - p01
        cross = d0 * e1 - d1 * e0
        if cross == 0.0:
            continue  # (meets nothing: the arrays' 0/0 and x/0 fail every comparison but !=)
        s = (w0 * e1 - w1 * e0) / cross
        w = (w0 * d1 - w1 * d0) / cross
        if not (w >= 0.0 and w <= 1.0 and s >= lo_t and s <= hi_t):
            continue
        if not (abs(cross) >= _STRAIGHT_MIN_SINE * dn * length and w * length > margin
                and (1.0 - w) * length > margin and (s - lo_t) * dn > margin and (hi_t - s) * dn > margin):
            return None
        found.append(s)
    least = math.inf
    for (a0, a1), (e0, e1), _, ll in sides:
        for v0, v1 in ((a0, a1), (a0 + e0, a1 + e1)):
            tv = min(max(((v0 - p00) * d0 + (v1 - p01) * d1) / (dn * dn), lo_t), hi_t)
            least = min(least, math.hypot(v0 - p00 - tv * d0, v1 - p01 - tv * d1))
        for b0, b1 in B:
            fb = min(max(((b0 - a0) * e0 + (b1 - a1) * e1) / ll, 0.0), 1.0)
            least = min(least, math.hypot(b0 - a0 - fb * e0, b1 - a1 - fb * e1))
    band = 1e-12 * size
    if least <= margin - band:
        return None
    if least <= margin + band:
        return _UNDECIDED
    return found


def _clip_straight(X: _Operand, f: int, pcurve, t0: float, t1: float, t: Tolerance
                   ) -> list[tuple[float, float, str]] | None:
    """``clip_to_face`` of a straight p-curve on a face bounded by straight p-curves, in closed form, or None.

    Preconditions (else None, and ``clip_to_face`` runs): the p-curve is a ``Line2D``; the face
    lies on a plane or a cylinder (where ``(u · s_u, v · s_v)`` with the constant speeds ``s_u,
    s_v`` is a local isometry, so distances in it are distances along the surface); every edge
    use has a ``Line2D`` p-curve and a tolerance within ``tol.linear``.  The face's loops are
    then exactly the polygon ``X.segments[f]`` (each edge sampled at its two ends, pole gaps
    closed by straight segments as ``clip_to_face``'s virtual pieces).  Each polygon side
    either crosses the branch properly (at a sine of at least :data:`_STRAIGHT_MIN_SINE`, away
    from the side's ends and the branch's ends by more than :data:`_STRAIGHT_CLEARANCE`
    tolerances) or stays farther than that from it; the crossings are then solved exactly (two
    lines), and the pieces between them are classified by one midpoint each against the
    polygon.  Any touching, grazing, overlap, crossing at a vertex or branch end on the
    boundary returns None.  The crossings are the plane solution that ``clip_to_face``
    refines in space; both p-curves are exact within ``tol.linear`` here, so the refinement
    moves them by at most that over the sine.  An empty answer on a periodic surface also
    returns None (as in :func:`_clip`).  The face's own part (:func:`_straight_data`) is
    computed once per face; the branch's few values are Python floats.
    """
    from coons.booleans.classify import _in_polygon

    if not isinstance(pcurve, Line2D):
        return None
    data = _straight_data(X, f, t)
    if data is None:
        return None
    sp, A, E, L, LL, V, largest, sides, size = data
    lo_t, hi_t = (t0, t1) if t0 < t1 else (t1, t0)
    # Work in the isometric coordinates: (k, 2) side starts A and vectors E, branch p0 + s d.
    o, dd = pcurve.origin, pcurve.direction
    p0, d = o * sp, dd * sp
    (p00, p01), (d0, d1) = p0.tolist(), d.tolist()
    B = np.array([[p00 + lo_t * d0, p01 + lo_t * d1], [p00 + hi_t * d0, p01 + hi_t * d1]])  # the branch's ends
    scale = 1.0 + max(largest, max(map(abs, B.ravel().tolist())))
    # clip_to_face's own band is one tolerance (tol3: the edges' and tol.linear); 1e-12 of the
    # coordinates' size covers the round-off of this arithmetic.
    margin = _STRAIGHT_CLEARANCE * t.linear + 1e-12 * scale
    dn = math.hypot(d0, d1)
    if len(sides) <= _SCALAR_SIDES:
        found = _straight_crossings(sides, (p00, p01), (d0, d1), B.tolist(), lo_t, hi_t, dn, margin,
                                    max(scale, size))
        if found is None:
            return None
        if found is _UNDECIDED:  # a clearance within round-off of the margin: the arrays decide
            found = _straight_crossings_arrays(A, E, L, LL, V, p0, d, B, lo_t, hi_t, dn, margin)
    else:
        found = _straight_crossings_arrays(A, E, L, LL, V, p0, d, B, lo_t, hi_t, dn, margin)
    if found is None:
        return None
    # (np.sort's order of equal keys, e.g. -0.0 and 0.0, is its own: it sorts those)
    br = [lo_t] + (np.sort(np.array(found)).tolist() if 0.0 in found else sorted(found)) + [hi_t]
    if any((b - a) * dn <= margin for a, b in zip(br[:-1], br[1:])):
        return None  # two crossings at one place: a vertex, let the general path decide
    mid = np.array([0.5 * (a + b) for a, b in zip(br[:-1], br[1:])])
    Q = o[None, :] + mid[:, None] * dd[None, :]
    inside = _in_polygon(Q, X.segments[f], _slopes(X, f)).tolist()
    out: list[list] = []
    for k in range(mid.size):
        if out and out[-1][2] == inside[k]:
            out[-1][1] = br[k + 1]
        else:
            out.append([br[k], br[k + 1], inside[k]])
    res = [(a, b, "inside") for a, b, ins in out if ins]
    S = X.specs[f].surface
    if not res and (getattr(S, "periodic_u", False) or getattr(S, "periodic_v", False)):
        return None  # (as in _clip: a period away is the general path's business)
    if t0 > t1:
        res = [(b, a, w_) for a, b, w_ in reversed(res)]
    return res


#: Up to this many cut ends on a face :func:`_check_cut_ends` pairs them in Python floats.
_SCALAR_ENDS = 16


def _distance(p, q) -> float:
    """``np.linalg.norm(p - q, axis=-1)`` of two 3-D points given as sequences of floats: the same
    expression, ``sqrt((x² + y²) + z²)`` (numpy sums the squares along a short axis in order)."""
    x, y, z = p[0] - q[0], p[1] - q[1], p[2] - q[2]
    return math.sqrt((x * x + y * y) + z * z)


def _open_cut_ends(cuts: list[EdgeSpec], t: Tolerance) -> tuple[list[list[float]], list[float]]:
    """The two ends ``[x, y, z]`` of each cut of :func:`_check_cut_ends` that is not closed (its ends farther
    apart than its threshold ``max(t.linear, tol)``), in order, and each end's threshold."""
    from coons.kernel.intersect import _curve_points

    ends, thr = [], []
    # Many cuts (a plate crossed by many holes): the ends of those on lines and conics in one pass
    # (evaluate_curves: the same expressions).
    simple = [k for k, c in enumerate(cuts) if type(c.curve) in (Line, Circle, Ellipse)
              and math.isfinite(c.t0) and math.isfinite(c.t1)] if len(cuts) > _SCALAR_ENDS else []
    ends_of = evaluate_curves([cuts[k].curve for k in simple], np.array([[cuts[k].t0, cuts[k].t1] for k in simple])) \
        if simple else None
    if simple and len(simple) == len(cuts):
        # All of them: the gaps in arrays too, _distance's expression coordinate by coordinate (the same floats).
        D = ends_of[:, 0] - ends_of[:, 1]
        gap = np.sqrt((D[:, 0] * D[:, 0] + D[:, 1] * D[:, 1]) + D[:, 2] * D[:, 2])
        lim = np.array([max(t.linear, c.tol or 0.0) for c in cuts])
        for k in np.flatnonzero(np.abs(gap - lim) <= 1e-9 * lim).tolist():  # (near ties: as below)
            gap[k] = np.linalg.norm(ends_of[k, 0] - ends_of[k, 1])
        open_ = gap > lim  # (closed cuts have no ends)
        ends, thr = ends_of[open_].reshape(-1, 3).tolist(), np.repeat(lim[open_], 2).tolist()
    else:
        known = dict(zip(simple, ends_of)) if simple else {}
        for k, c in enumerate(cuts):
            tt = np.array([c.t0, c.t1])
            P = known[k] if k in known else _curve_points(c.curve, tt) if math.isfinite(c.t0) and math.isfinite(c.t1) \
                else np.asarray(c.curve.evaluate(tt), dtype=np.float64)
            lim = max(t.linear, c.tol or 0.0)
            p, q = P.tolist()
            gap = _distance(p, q)
            if abs(gap - lim) <= 1e-9 * lim:  # a near tie: numpy's norm of a vector (its dot product rounds its own way)
                gap = float(np.linalg.norm(P[0] - P[1]))
            if gap > lim:  # closed cuts have no ends
                ends += [p, q]
                thr += [lim, lim]
    return ends, thr


def _check_cut_ends(X: _Operand, f: int, cuts: list[EdgeSpec], Y: _Operand, t: Tolerance) -> None:
    """Every end of a cut on face ``f`` of X must meet another cut's end, the face's boundary or an edge of Y.

    Intersection curves of closed surfaces are closed or end on the faces' boundaries (of X's
    face, or of the other operand's face: a tangent line of contact ends at the rim of a
    cylinder); a cut ending elsewhere means a branch is missing (an incomplete surface
    intersection), which would otherwise surface later as an open shell.

    The ends that meet no other end are measured against the face's edges, skipping those whose
    proven box (:meth:`_Operand.edge_boxes`) lies farther than twice the threshold from all of
    them (they cannot bring an end within it); when an end stays beyond the threshold, the
    complete check (:func:`_check_cut_ends_all`: every edge, then Y's) decides and reports.  The
    distances are those of the complete check (the same products on the same points; a line's
    foot and distance in Python floats by the expressions of ``evaluate`` and ``np.linalg.norm``).

    Raises
    ------
    BooleanError
        (stage ``"intersect"``) naming the face, the dangling point and its distances.
    """
    from coons.booleans.classify import _curve_closest

    ends, thr = _open_cut_ends(cuts, t)
    if not ends:
        return
    # Ends meeting another end.
    if len(ends) <= _SCALAR_ENDS:  # (np.linalg.norm along the last axis is sqrt((x² + y²) + z²))
        todo = [i for i, (a, ta) in enumerate(zip(ends, thr))
                if not any(j != i and _distance(a, b) <= max(ta, tb) for j, (b, tb) in enumerate(zip(ends, thr)))]
    else:  # candidate pairs from a k-d tree (within twice the widest threshold), then the same test on them
        from scipy.spatial import cKDTree

        E, th = np.array(ends), np.array(thr)
        met = np.zeros(len(ends), dtype=bool)
        pairs = cKDTree(E).query_pairs(r=2.0 * float(th.max()), output_type="ndarray")
        if pairs.size:
            p, q = pairs[:, 0], pairs[:, 1]
            hit = np.linalg.norm(E[p] - E[q], axis=-1) <= np.maximum(th[p], th[q])
            met[p[hit]] = met[q[hit]] = True
        todo = np.flatnonzero(~met).tolist()
    if not todo:
        return
    Q = np.array([ends[i] for i in todo])
    limit = [max(thr[i], t.linear) * 10.0 for i in todo]
    edges, lo, hi, _ = X.edge_boxes(f)
    reach = 2.0 * max(limit)
    clear = np.all(np.any((Q[None] < lo[:, None] - reach) | (Q[None] > hi[:, None] + reach), axis=2), axis=1)
    best = [math.inf] * len(todo)
    for k in np.flatnonzero(~clear).tolist():
        e = edges[k]
        e_lo, e_hi = min(e.t0, e.t1), max(e.t0, e.t1)
        tq = np.clip(_curve_closest(e.curve, Q, e_lo, t), e_lo, e_hi)
        if type(e.curve) is Line:
            O, D = e.curve.origin.tolist(), e.curve.direction.tolist()
            d = [_distance([O[0] + s * D[0], O[1] + s * D[1], O[2] + s * D[2]], q)
                 for s, q in zip(tq.tolist(), Q.tolist())]
        else:
            d = np.linalg.norm(np.asarray(e.curve.evaluate(tq)).reshape(-1, 3) - Q, axis=1).tolist()
        best = [min(x, y) for x, y in zip(best, d)]
    if any(b > m for b, m in zip(best, limit)):
        _check_cut_ends_all(X, f, cuts, Y, t)


def _check_cut_ends_all(X: _Operand, f: int, cuts: list[EdgeSpec], Y: _Operand, t: Tolerance) -> None:
    """The complete check of :func:`_check_cut_ends` (every end against every edge), which raises."""
    from coons.booleans.classify import _curve_closest

    ends = []
    for c in cuts:
        P = np.asarray(c.curve.evaluate(np.array([c.t0, c.t1])), dtype=np.float64)
        if np.linalg.norm(P[0] - P[1]) > max(t.linear, c.tol or 0.0):  # closed cuts have no ends
            ends.extend([(P[0], c), (P[1], c)])
    if not ends:
        return
    E = np.array([p for p, _ in ends])
    thr = np.array([max(t.linear, c.tol or 0.0) for _, c in ends])
    D = np.linalg.norm(E[:, None] - E[None], axis=-1)
    np.fill_diagonal(D, np.inf)
    met = np.any(D <= np.maximum(thr[:, None], thr[None]), axis=1)
    todo = np.flatnonzero(~met)
    if todo.size == 0:
        return
    Q = E[todo]
    best = np.full(todo.size, np.inf)
    for loop in X.specs[f].loops:
        for e in loop:
            lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
            tq = np.clip(_curve_closest(e.curve, Q, lo, t), lo, hi)
            d = np.linalg.norm(np.asarray(e.curve.evaluate(tq)).reshape(-1, 3) - Q, axis=1)
            best = np.minimum(best, d)
    far = best > np.maximum(thr[todo], t.linear) * 10.0
    if np.any(far):  # on an edge of the other operand?
        from coons.booleans.classify import _edge_closest

        b = Y.solid.brep
        sel = np.flatnonzero(far)
        for e in range(b.n_edges):
            _, q, _ = _edge_closest(b, e, Q[sel], t)
            best[sel] = np.minimum(best[sel], np.linalg.norm(q - Q[sel], axis=1))
    bad = np.flatnonzero(best > np.maximum(thr[todo], t.linear) * 10.0)
    if bad.size:
        k = int(bad[0])
        raise BooleanError(
            f"operand {X.name}, face {f} ({_kind(X.specs[f])}): a cut ends at {Q[k].tolist()}, {best[k]:.3g} from the "
            f"face's boundary and the other operand's edges and away from every other cut end; expected intersection curves that close or end on "
            "the boundary (a branch of a surface intersection is missing)",
            stage="intersect", diagnostics={"operand": X.name, "face": f, "point": Q[k].tolist(),
                                            "boundary_distance": float(best[k])})


#: Up to this many edges of a face :func:`_end_tolerance` tests their boxes in Python floats.
_SCALAR_BOXES = 16

#: Smallest sine of a crossing angle used to widen an end's tolerance: a curve grazing a boundary
#: closer than this (0.06°) is treated as touching, its end uncertain by at most 1000 tolerances.
_MIN_SINE = 1e-3


def _end_tolerance(c, ends: tuple[float, float], faces: tuple, t: Tolerance, near: list | None = None) -> float:
    """Tolerance of a cut whose ends were found where the branch crosses the faces' boundaries.

    Two curves known within ``δ`` that cross at an angle ``φ`` meet at a point known along them
    within ``δ / sin φ``; the faces on both sides of a boundary edge compute that point
    independently (each in its own parameter plane), so near-grazing crossings give end points
    that differ by more than ``δ``.  The cut records ``δ / sin φ`` (``δ`` the branch's and the
    boundary edge's tolerance), which lets sewing merge the two ends into one vertex.

    ``faces``: for each of the two faces, :meth:`_Operand.edge_boxes` (its edge uses, their boxes
    and tolerances): only the edges whose box comes near an end are examined.  ``near`` (when
    given: per face, per end, ``inf`` to start with) receives the least distance from the end to
    an examined edge on a line, circle or ellipse, plus a bound on the round-off by which
    :func:`_check_cut_ends_all` may measure it differently (``1e-12`` of the coordinates' size,
    thousands of times the few ulps of the same formulas on arrays of other shapes).
    """
    from coons.kernel.intersect import _curve_tangents

    base = max(t.linear, c.tol)
    ts = np.asarray(ends, dtype=np.float64)
    if math.isfinite(ends[0]) and math.isfinite(ends[1]):
        P, T = _curve_tangents(c.curve, ts)  # (derivatives' expressions)
    else:
        D = np.asarray(c.curve.derivatives(ts, 1), dtype=np.float64)
        P, T = D[:, 0], D[:, 1]
    # (np.linalg.norm's own expression along an axis)
    T = T / np.maximum(np.sqrt(np.add.reduce(T * T, axis=1, keepdims=True)), 1e-300)
    worst = base
    ends_list = P.tolist()
    size = 1.0 + max(abs(x) for p in ends_list for x in p)
    for side, (edges, lo, hi, tol) in enumerate(faces):
        for k in _near_boxes(ends_list, P, lo, hi, 10.0 * np.maximum(base, tol)):  # an end near the edge's box
            e = edges[k]
            lo_t, hi_t = min(e.t0, e.t1), max(e.t0, e.t1)
            delta = max(base, e.tol or 0.0)
            d, sine = _end_sines(e.curve, P, T, lo_t, hi_t, 10.0 * delta, t)
            on = [x for x, y in zip(sine, d) if y <= 10.0 * delta]  # at the ends on this boundary edge
            if on:
                w = max(delta / x for x in on)
                # A cut running along the edge (a circle of an earlier Boolean cut again by the
                # same plane) ends where another edge crosses it: this one's tangent says nothing.
                if w <= 10.0 * delta or not _runs_along(c.curve, e.curve, lo_t, hi_t, delta):
                    worst = max(worst, w)
            if near is not None and type(e.curve) in (Line, Circle, Ellipse):
                O = (e.curve.origin if type(e.curve) is Line else e.curve._origin).tolist()
                slack = 1e-12 * (size + max(map(abs, O)))
                near[side] = [min(x, y + slack) for x, y in zip(near[side], d)]
    return worst


def _runs_along(branch, curve, lo_t: float, hi_t: float, delta: float) -> bool:
    """Whether the line or circle ``curve`` over ``[lo_t, hi_t]`` lies within ``delta`` of the branch's
    line or circle (its ends and middle do: three points of a circle on a circle make it that
    circle, two of a line that line).  Other curves, or a curve of another kind than the branch's:
    False (the widened tolerance stays)."""
    kind = type(branch)
    if (kind is not Line and kind is not Circle) or type(curve) is not kind:
        return False
    Q = np.asarray(curve.evaluate(np.array([lo_t, 0.5 * (lo_t + hi_t), hi_t])), dtype=np.float64)
    if kind is Line:
        D = branch.direction / np.linalg.norm(branch.direction)
        R = Q - branch.origin
        dist = np.linalg.norm(R - np.outer(R @ D, D), axis=1)
    else:
        Z = branch.axis / np.linalg.norm(branch.axis)
        R = Q - branch.center
        h = R @ Z
        dist = np.hypot(np.linalg.norm(R - np.outer(h, Z), axis=1) - branch.radius, h)
    return bool(np.all(dist <= delta))


def _near_boxes(points: list, P: np.ndarray, lo: np.ndarray, hi: np.ndarray, reach: np.ndarray) -> list[int]:
    """Indices of the boxes ``[lo - reach, hi + reach]`` (``(k, 3)``, ``(k,)``) that hold one of the points ``P``
    (``(m, 3)``, also as ``points``, a list); a few boxes in Python floats (the same comparisons)."""
    if len(reach) > _SCALAR_BOXES:
        far = np.any((P[None] < lo[:, None] - reach[:, None, None]) | (P[None] > hi[:, None] + reach[:, None, None]),
                     axis=2)
        return np.flatnonzero(~np.all(far, axis=1)).tolist()
    out = []
    for k, (a, b, r) in enumerate(zip(lo.tolist(), hi.tolist(), reach.tolist())):
        a, b = [x - r for x in a], [x + r for x in b]
        if any(a[0] <= p[0] <= b[0] and a[1] <= p[1] <= b[1] and a[2] <= p[2] <= b[2] for p in points):
            out.append(k)
    return out


def _end_sines(curve, P: np.ndarray, T: np.ndarray, lo_t: float, hi_t: float, reach: float, t: Tolerance
               ) -> tuple[list[float], list[float]]:
    """For the ends ``P (2, 3)``, their distances to ``curve([lo_t, hi_t])`` and the sines of the angle between
    the branch's unit tangent ``T`` there and the curve's at the foot (at least :data:`_MIN_SINE`).

    A line in Python floats: the expressions of ``derivatives``, ``np.linalg.norm`` along a
    3-vector (:func:`_distance`) and ``_cross``, one end at a time; its sines do not depend on the
    feet, and the feet only decide whether a distance is within ``reach``: where one lies within
    ``1e-12`` of the coordinates' size of it (numpy's matrix product rounds the projection its
    own way, by a few ulps), the feet are taken from that product as ``closest_parameters`` does.
    Other curves in arrays.
    """
    from coons.booleans.classify import _curve_closest
    from coons.kernel.intersect import _cross

    if type(curve) is Line:
        O, D = curve.origin.tolist(), curve.direction.tolist()
        ends = P.tolist()
        te = [min(max(((p[0] - O[0]) * D[0] + (p[1] - O[1]) * D[1]) + (p[2] - O[2]) * D[2], lo_t), hi_t) for p in ends]
        dist = [_distance([O[0] + s * D[0], O[1] + s * D[1], O[2] + s * D[2]], p) for s, p in zip(te, ends)]
        band = 1e-12 * (1.0 + max(abs(x) for p in ends for x in p) + max(map(abs, O)))
        if any(abs(x - reach) <= band for x in dist):
            te = np.clip((P - curve.origin) @ curve.direction, lo_t, hi_t).tolist()
            dist = [_distance([O[0] + s * D[0], O[1] + s * D[1], O[2] + s * D[2]], p) for s, p in zip(te, ends)]
        size = max(math.sqrt((D[0] * D[0] + D[1] * D[1]) + D[2] * D[2]), 1e-300)
        b0, b1, b2 = D[0] / size, D[1] / size, D[2] / size
        sines = []
        for a0, a1, a2 in T.tolist():
            c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
            sines.append(max(math.sqrt((c0 * c0 + c1 * c1) + c2 * c2), _MIN_SINE))
        return dist, sines
    te = np.clip(_curve_closest(curve, P, lo_t, t), lo_t, hi_t)
    De = np.asarray(curve.derivatives(te, 1), dtype=np.float64)
    d = np.linalg.norm(De[:, 0] - P, axis=1)
    Te = De[:, 1] / np.maximum(np.linalg.norm(De[:, 1], axis=1, keepdims=True), 1e-300)
    sine = np.maximum(np.linalg.norm(_cross(T, Te), axis=1), _MIN_SINE)
    return d.tolist(), sine.tolist()


def _edge_boxes(edges: list[EdgeSpec]) -> list[np.ndarray | None]:
    """Proven boxes ``(2, 3)`` around the uses' curves over their ranges (lines, conics and NURBS,
    together by :func:`~coons.kernel.curve_intersect.curve_boxes`), None for other curve types."""
    boxes, boxed = _edge_box_array(edges)
    return [box if ok else None for box, ok in zip(boxes, boxed.tolist())]


def _edge_box_array(edges: list[EdgeSpec]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_edge_boxes` as one read-only ``(k, 2, 3)`` array (rows of uses without a box: ``nan``)
    and ``(k,)`` bool where there is a box."""
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.curve_intersect import curve_boxes

    boxed = np.array([isinstance(e.curve, (Line, Circle, Ellipse, NurbsCurve)) for e in edges], dtype=bool)
    if not edges:
        return _frozen(np.empty((0, 2, 3))), boxed
    uses = edges if boxed.all() else [e for e, ok in zip(edges, boxed.tolist()) if ok]
    got = np.empty((0, 2, 3))
    if uses:
        # Each distinct (curve, range) once: the two uses of an edge (its faces' loops, opposite ways
        # round) have one box (curve_boxes orders each range; a hundred tools bring six hundred edges).
        t0 = np.array([e.t0 for e in uses], dtype=np.float64)
        t1 = np.array([e.t1 for e in uses], dtype=np.float64)
        lo, hi = np.minimum(t0, t1), np.maximum(t0, t1)
        first, of = row_groups(np.fromiter(map(id, (e.curve for e in uses)), dtype=np.int64, count=len(uses)), lo, hi)
        got = curve_boxes([uses[i].curve for i in first.tolist()], lo[first], hi[first])[of]
    if len(uses) == len(edges):
        boxes = got
    else:
        boxes = np.full((len(edges), 2, 3), np.nan)
        boxes[boxed] = got
    boxes.setflags(write=False)  # (each use's box a view: the batch lives while one of them is cached)
    return boxes, boxed


def _imprint(X: FaceSpec, Y: FaceSpec, box_x, out: list[EdgeSpec], t: Tolerance) -> None:
    """Append to ``out`` the parts of Y's boundary edges that run inside X (X, Y on one surface)."""
    from coons.kernel.onsurface import pcurve_on
    from coons.topology.split import clip_to_face

    for loop in Y.loops:
        for e in loop:
            lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
            pc, dev = pcurve_on(X.surface, e.curve, lo, hi, box=box_x, tol=t)
            for s0, s1, where in clip_to_face(X, pc, lo, hi, t, curve=e.curve):
                if where == "inside" and s1 > s0 and _long_enough(e.curve, s0, s1, t):
                    out.append(EdgeSpec(e.curve, s0, s1, pc, max(dev, e.tol or 0.0)))


def _long_enough(curve, s0: float, s1: float, t: Tolerance, reach: float | None = None) -> bool:
    """A cut must leave the tolerance ball of its start somewhere (else it is a point); the ball's
    radius is ``reach`` when given (a cut's own tolerance), else ``t.linear``."""
    r = t.linear if reach is None else reach
    if type(curve) in (Line, Circle, Ellipse) and math.isfinite(s0) and math.isfinite(s1):
        from coons.kernel.intersect import _curve_points

        # evaluate's points; their distances by np.linalg.norm's expression (_distance)
        P = _curve_points(curve, np.linspace(s0, s1, 5)).tolist()
        return max(_distance(p, P[0]) for p in P) > r
    P = np.asarray(curve.evaluate(np.linspace(s0, s1, 5)))
    return bool(np.max(np.linalg.norm(P - P[0], axis=1)) > r)


#: Up to this many cuts on a face :func:`_unique_cuts` first tests in Python floats whether any two
#: midpoints come near (a face crossed by a few branches: usually none do).
_SCALAR_CUTS = 16


#: Up to this many groups :func:`_apart_many` tests their pairs in Python floats.
_SCALAR_GROUPS = 16


def _apart_many(groups: list[list[EdgeSpec]], t: Tolerance) -> list[bool]:
    """Per group of cuts, whether no two cuts' midpoints lie within twice the group's widest cut
    tolerance: then no two are within it, and the k-d tree of :func:`_unique_cuts` (whose distances
    differ from these by round-off) finds no pair.  The midpoints of all groups are evaluated
    together (:func:`~coons.kernel.onsurface.evaluate_curves` for lines and conics)."""
    cuts = [c for g in groups for c in g]
    if not cuts:
        return [True] * len(groups)
    tm = [0.5 * (c.t0 + c.t1) for c in cuts]
    simple = [k for k, c in enumerate(cuts) if type(c.curve) in (Line, Circle, Ellipse) and math.isfinite(tm[k])]
    M = np.empty((len(cuts), 3))
    if simple:
        M[simple] = evaluate_curves([cuts[k].curve for k in simple], np.array([[tm[k]] for k in simple]))[:, 0]
    if len(simple) < len(cuts):
        for k in sorted(set(range(len(cuts))) - set(simple)):
            M[k] = np.asarray(cuts[k].curve.evaluate(np.array([tm[k]])), dtype=np.float64).reshape(3)
    if len(groups) <= _SCALAR_GROUPS:  # (a few faces: Python floats, without the arrays' fixed cost)
        mids = M.tolist()
        out, s0 = [], 0
        for g in groups:
            r = 2.0 * max(max(t.linear, c.tol or 0.0) for c in g)
            m = mids[s0:s0 + len(g)]
            s0 += len(g)
            out.append(all(_distance(p, q) > r for i, p in enumerate(m) for q in m[:i]))
        return out
    # Every pair of one group's cuts at once (the walls of a hundred holes: two cuts each), grouped by the
    # groups' sizes; the distances by _distance's expression coordinate by coordinate (the same floats).
    n = np.array([len(g) for g in groups])
    start = np.cumsum(n) - n
    thr = np.array([max(t.linear, c.tol or 0.0) for c in cuts])
    r = np.zeros(len(groups))
    r[n > 0] = 2.0 * np.maximum.reduceat(thr, start[n > 0])  # (the groups' widest tolerances, twice)
    close = np.zeros(len(groups), dtype=bool)
    for size in np.unique(n[n >= 2]).tolist():
        rows = np.flatnonzero(n == size)
        i, j = np.tril_indices(size, -1)
        D = M[start[rows, None] + i] - M[start[rows, None] + j]  # (rows, pairs, 3)
        d = np.sqrt((D[..., 0] * D[..., 0] + D[..., 1] * D[..., 1]) + D[..., 2] * D[..., 2])
        close[rows] = np.any(~(d > r[rows, None]), axis=1)  # (not apart: a NaN distance too)
    return (~close).tolist()


#: Where along a cut that ends on another cut the run-along test of :func:`_split_overlaps` looks
#: (fraction of the ending cut's parameter range from that end).
_ALONG_FRACTION = 0.1


def _resplit_along(cuts: dict[int, list[EdgeSpec]], along: set[int], t: Tolerance) -> set[int]:
    """Split in place the cuts of every face that has two or more cuts along the other operand's
    edges (``along``: their ids) by :func:`_split_overlaps`; the faces whose cuts changed.

    Only such cuts can overlap: a cut inside a face of the other operand lies off that operand's
    edges, and the other operand's faces do not overlap."""
    faces = [f for f, cs in cuts.items() if len(cs) >= 2 and sum(id(c) in along for c in cs) >= 2]
    if not faces:
        return set()
    groups = [[c for c in cuts[f] if id(c) in along] for f in faces]
    changed = set()
    for f, g, split in zip(faces, groups, _split_overlaps(groups, t)):
        if split is None:
            continue
        pieces = {id(c): p for c, p in zip(g, split)}
        cuts[f] = [e for c in cuts[f] for e in pieces.get(id(c), (c,))]
        changed.add(f)
    return changed


def _split_overlaps(groups: list[list[EdgeSpec]], t: Tolerance) -> list[list[list[EdgeSpec]] | None]:
    """Per group of one face's cuts: per cut, its pieces split at the ends of other cuts of the group
    that run along it (the group None where no cut ends inside another).

    A branch along an edge chain of the other operand can be found twice on this face with
    different ends: as the section of a face that the chain bounds (one cut, blind to the chain's
    vertices) and as the imprint of a coincident face (one cut per edge of the chain), or by two
    faces whose runs along the chain end at different vertices.  Split at each other's ends, the
    overlapping stretches become repeats that :func:`_unique_cuts` drops; left whole, one copy
    survives beside the other and ``split_face`` leaves it dangling (three cylinders sharing
    their cap planes, ``(A & B) & C``).  An end counts when it lies on the other cut's interior
    (within both cuts' tolerances) and the ending cut's point a tenth of the way in lies on the
    other's curve too: a cut leaving another across it (a T) does not split it.

    Candidates come from one k-d tree over all cut ends, queried with the balls around the cuts'
    proven boxes (:func:`_edge_box_array`; a cut without one takes every end); only candidates of
    the same face, in the cut's box padded by the tolerance and away from its ends get
    closest-point tests.
    """
    from scipy.spatial import cKDTree

    from coons.booleans.classify import _curve_closest

    out: list[list[EdgeSpec] | None] = [None] * len(groups)
    flat = [c for g in groups for c in g]
    if not flat:
        return out
    n = len(flat)
    E = _cut_ends(flat)  # (2 n, 3)
    E0, E1 = E[0::2], E[1::2]
    thr = np.array([max(t.linear, c.tol or 0.0) for c in flat])
    box, boxed = _edge_box_array(flat)
    box_lo = np.where(boxed[:, None], box[:, 0], -np.inf) - thr.max()
    box_hi = np.where(boxed[:, None], box[:, 1], np.inf) + thr.max()
    sizes = np.array([len(g) for g in groups])
    owner = np.repeat(np.arange(len(groups)), sizes)  # face of each cut
    with np.errstate(invalid="ignore"):  # (inf - inf of a cut without a box: its centre is not used)
        centre = np.where(boxed[:, None], 0.5 * (box_lo + box_hi), 0.0)
    radius = np.where(boxed, 0.5 * np.linalg.norm(np.where(boxed[:, None], box_hi - box_lo, 0.0), axis=1), 1e300)
    hits = cKDTree(E).query_ball_point(centre, radius, return_sorted=False)
    counts = np.fromiter((len(h) for h in hits), dtype=np.intp, count=n)
    qi = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.intp, count=int(counts.sum()))
    ci = np.repeat(np.arange(n), counts)
    keep = (owner[qi // 2] == owner[ci]) & (qi // 2 != ci)
    qi, ci = qi[keep], ci[keep]
    th = np.maximum(thr[ci], thr[qi // 2])
    Q = E[qi]
    d0, d1 = np.linalg.norm(Q - E0[ci], axis=1), np.linalg.norm(Q - E1[ci], axis=1)
    inside = np.all((Q >= box_lo[ci]) & (Q <= box_hi[ci]), axis=1) & (d0 > th) & (d1 > th)
    if not inside.any():
        return out
    at: dict[int, list[float]] = {}
    for q, c, h in zip(qi[inside].tolist(), ci[inside].tolist(), th[inside].tolist()):
        cut, d = flat[c], flat[q // 2]
        lo, hi = min(cut.t0, cut.t1), max(cut.t0, cut.t1)
        s = float(_curve_closest(cut.curve, E[q][None], lo, t)[0])
        if not lo < s < hi or _distance(np.asarray(cut.curve.evaluate(np.array([s]))).reshape(3).tolist(),
                                        E[q].tolist()) > h:
            continue
        e0, e1 = (d.t0, d.t1) if q % 2 == 0 else (d.t1, d.t0)
        P = np.asarray(d.curve.evaluate(np.array([e0 + _ALONG_FRACTION * (e1 - e0)]))).reshape(1, 3)
        s_in = float(_curve_closest(cut.curve, P, lo, t)[0])
        if _distance(np.asarray(cut.curve.evaluate(np.array([s_in]))).reshape(3).tolist(), P[0].tolist()) > h:
            continue  # d leaves the cut across it
        at.setdefault(c, []).append(s)
    first = np.concatenate(([0], np.cumsum(sizes)[:-1])).tolist()
    for g, cs in enumerate(groups):
        o = first[g]
        if not any(o + k in at for k in range(len(cs))):
            continue
        split: list[list[EdgeSpec]] = []
        for k, cut in enumerate(cs):
            if o + k not in at:
                split.append([cut])
                continue
            # split points closer than tolerance (ends of two cuts at one vertex) are one
            ends = [cut.t0]
            for s in sorted(set(at[o + k]), reverse=cut.t1 < cut.t0):
                if _long_enough(cut.curve, min(ends[-1], s), max(ends[-1], s), t):
                    ends.append(s)
            if len(ends) > 1 and not _long_enough(cut.curve, min(ends[-1], cut.t1), max(ends[-1], cut.t1), t):
                ends.pop()
            ends.append(cut.t1)
            split.append([EdgeSpec(cut.curve, a, b, cut.pcurve, cut.tol) for a, b in zip(ends[:-1], ends[1:])])
        out[g] = split
    return out


def _unique_cuts(cuts: list[EdgeSpec], t: Tolerance, repeated: set[int] | None = None,
                 apart: bool | None = None) -> list[EdgeSpec]:
    """Drop cuts that repeat an earlier one (same end points and midpoint within tolerance, either way).

    Candidates are found by a k-d tree on the midpoints (within the widest cut tolerance), so the
    cost is about linear in the number of cuts.  ``repeated`` (when given) receives the ``id``
    of the curve of every cut that repeats or is repeated by another.  Up to ``_SCALAR_CUTS``
    cuts, :func:`_apart_many`'s quick test comes first (``apart``: its answer when the caller
    has it).
    """
    from scipy.spatial import cKDTree

    n = len(cuts)
    if n < 2:
        return list(cuts)
    if n <= _SCALAR_CUTS and (_apart_many([cuts], t)[0] if apart is None else apart):
        return list(cuts)
    P = np.empty((n, 3, 3))
    groups: dict[int, list[int]] = {}
    simple = []  # cuts on lines and conics: all in one pass (evaluate_curves, evaluate's expressions)
    for k, c in enumerate(cuts):
        if type(c.curve) in (Line, Circle, Ellipse) and math.isfinite(c.t0) and math.isfinite(c.t1):
            simple.append(k)
        else:
            groups.setdefault(id(c.curve), []).append(k)
    if simple:
        t0 = np.array([cuts[k].t0 for k in simple])
        t1 = np.array([cuts[k].t1 for k in simple])
        P[simple] = evaluate_curves([cuts[k].curve for k in simple], np.stack([t0, 0.5 * (t0 + t1), t1], axis=1))
    for rows in groups.values():  # one evaluation per curve object
        r = np.asarray(rows)
        t0 = np.array([cuts[k].t0 for k in rows])
        t1 = np.array([cuts[k].t1 for k in rows])
        tt = np.stack([t0, 0.5 * (t0 + t1), t1], axis=1)
        P[r] = np.asarray(cuts[rows[0]].curve.evaluate(tt), dtype=np.float64).reshape(r.size, 3, 3)
    thr = np.array([max(t.linear, c.tol or 0.0) for c in cuts])
    pairs = cKDTree(P[:, 1]).query_pairs(r=float(thr.max()), output_type="ndarray")
    dropped = np.zeros(n, dtype=bool)
    if pairs.size:
        p, q = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        order = np.lexsort((p, q))  # later cut q first by q, then by the earlier cut p
        p, q = p[order], q[order]
        th = np.maximum(thr[p], thr[q])[:, None]
        same = np.all(np.linalg.norm(P[p] - P[q], axis=2) <= th, axis=1) \
            | np.all(np.linalg.norm(P[p][:, ::-1] - P[q], axis=2) <= th, axis=1)
        # A cut is dropped when it repeats an earlier cut that is itself kept (in order).
        for a, b in zip(p[same].tolist(), q[same].tolist()):
            if not dropped[a] and not dropped[b]:
                dropped[b] = True
            if repeated is not None:
                repeated.update((id(cuts[a].curve), id(cuts[b].curve)))
    return [c for k, c in enumerate(cuts) if not dropped[k]]


# ---------------------------------------------------------------------- split
def _split(X: _Operand, cuts: dict[int, list[EdgeSpec]], t: Tolerance) -> list[tuple[int, FaceSpec]]:
    """Pieces ``(original face, FaceSpec)`` of every face of one operand.

    Raises
    ------
    BooleanError
        (stage ``"split"``) ``split_face`` failed; the face and its cut count are named.
    """
    from coons.topology.split import split_face

    # The chord tests of all faces at once; should they fail, each face runs its own (and a
    # failure there names the face).
    try:
        chords = _chord_data(X, cuts, t)
    except (CoonsError, ValueError, ArithmeticError):
        chords = None
    out: list[tuple[int, FaceSpec]] = []
    for f, spec in enumerate(X.specs):
        if f not in cuts:
            out.append((f, spec))
            continue
        try:
            # (the chord test declines closed or curved cuts at once: try it first)
            pieces = _split_chords(X, f, cuts[f], t, chords)
            if pieces is None:
                pieces = _split_islands(X, f, cuts[f], t)
            direct = pieces is not None
            if pieces is None:
                pieces = split_face(spec, cuts[f], t)
        except (CoonsError, ValueError, ArithmeticError) as exc:
            raise BooleanError(
                f"operand {X.name}, face {f} ({_kind(spec)}) split by {len(cuts[f])} cut(s): {type(exc).__name__}: {exc}",
                stage="split", diagnostics={"operand": X.name, "face": f, "cuts": len(cuts[f]), "error": str(exc)},
            ) from exc
        if not direct:  # (the direct splits put every cut, whole, into two pieces, once each way)
            _check_cuts_used(X, f, cuts[f], pieces, t)
        out.extend((f, p) for p in pieces)
    return out


def _split_islands(X: _Operand, f: int, cuts: list[EdgeSpec], t: Tolerance) -> list[FaceSpec] | None:
    """The pieces of face ``f`` when its cuts form separate closed cycles clear of its boundary, else None.

    The common case of a tool passing through a face (a hole drilled through a plate): every cut
    stays clear of the face's loops (the box test of :func:`_clip`), the cuts join end to end
    into simple closed cycles whose parameter boxes are pairwise disjoint, and no existing loop
    of the face lies inside a cycle.  The pieces are then the face with each cycle added as a
    hole, and one island face per cycle, built directly instead of by ``split_face`` (whose
    cost grows with the number of cuts and loops).  Anything else returns None (``split_face``
    decides).

    Every test runs on all cuts or all cycles of the face at once (a plate face receiving 400
    holes in one call): the cuts' samples by p-curve kind (:func:`_cut_samples`), the end
    matching by a k-d tree, the box tests by :func:`~coons.booleans._broad_phase.box_pairs`,
    and the cycles' self-crossing, containment and area tests on the flat array of all their
    ring points (:func:`_cycle_tests`); only the walk along the cycles and the building of the
    face specs are Python loops, once per cut.
    """
    from scipy.spatial import cKDTree

    from coons.booleans.classify import _in_polygon

    spec = X.specs[f]
    n = len(cuts)
    if n == 0 or any(c.pcurve is None for c in cuts) or _fitted_end_near_loops(X, f, cuts):
        return None
    Q = _cut_samples(cuts)  # (n, _CLEAR_SAMPLES, 2)
    if Q is None or not np.all(np.isfinite(Q)):
        return None
    step = np.max(row_norms(np.diff(Q, axis=1)), axis=1)
    margin = step + 1e-9 * (1.0 + np.max(np.abs(Q), axis=(1, 2)))
    Q_lo, Q_hi = _middle_extremes(Q)
    lo, hi = Q_lo - margin[:, None], Q_hi + margin[:, None]
    if _boxes_meet_2d(lo, hi, X.seg_lo[f], X.seg_hi[f]):
        return None  # near the face's boundary: split_face decides
    # Join the cuts end to end: every end cluster must hold exactly two ends (end 2 k + which).
    E = _cut_ends(cuts)
    thr = np.repeat([max(t.linear, c.tol or 0.0) for c in cuts], 2)
    r = float(thr.max())
    # (the tree's distances may differ from norm's by round-off: query wider, decide by norm)
    pairs = cKDTree(E).query_pairs(r=r * (1.0 + 1e-9) + 1e-300, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    close = np.linalg.norm(E[i] - E[j], axis=-1) <= np.maximum(thr[i], thr[j])
    i, j = i[close], j[close]
    if i.size != n or np.any(np.bincount(np.concatenate([i, j]), minlength=2 * n) != 1):
        return None  # some end without exactly one partner
    partner = np.empty(2 * n, dtype=np.int64)
    partner[i] = j
    partner[j] = i
    # Walk the cycles: order[u], fwd[u] the cuts in traversal order, cycle starts in `starts`.
    partner_l = partner.tolist()
    seen = [False] * n
    order: list[int] = []
    fwd_l: list[bool] = []
    starts: list[int] = []
    for k0 in range(n):
        if seen[k0]:
            continue
        starts.append(len(order))
        k, fwd = k0, True
        while True:
            if seen[k]:
                if k != k0 or not fwd:
                    return None
                break
            seen[k] = True
            order.append(k)
            fwd_l.append(fwd)
            p = partner_l[2 * k + (1 if fwd else 0)]
            k, fwd = p // 2, p % 2 == 0
    o = np.asarray(order, dtype=np.int64)
    fw = np.asarray(fwd_l, dtype=bool)
    Qo = Q[o]
    Qo[~fw] = Qo[~fw, ::-1]  # each use's samples in its direction of travel
    c0 = np.asarray(starts, dtype=np.int64)
    size = np.diff(np.append(c0, n))
    # Closed in the parameter plane too (not around a pole or across a period): the gap from
    # each use's last sample to the next use's first, against the cycle's span.
    nxt = np.arange(n) + 1
    nxt[c0 + size - 1] = c0
    gaps = np.linalg.norm(Qo[:, -1] - Qo[nxt, 0], axis=-1)
    Qo_lo, Qo_hi = _middle_extremes(Qo)
    span = np.max(np.maximum.reduceat(Qo_hi, c0, axis=0) - np.minimum.reduceat(Qo_lo, c0, axis=0),
                  axis=1)
    # parameter round-off of joined ends, far below a sample step
    if np.any(np.maximum.reduceat(gaps, c0) > 1e-6 * (1.0 + span)):
        return None
    rings = Qo[:, 1:]  # each first sample is (within the gap) the previous use's last
    # Separate cycles: their rings' boxes pairwise apart.
    if c0.size > 1:
        r_lo, r_hi = _middle_extremes(rings)
        clo = np.minimum.reduceat(r_lo, c0, axis=0)
        chi = np.maximum.reduceat(r_hi, c0, axis=0)
        if _boxes_meet_2d(clo, chi, clo, chi, skip_self=True):
            return None
    # Simple cycles, none around an existing loop of the face, each inside the face, not flat.
    # The probes are the loops' first points (their first segments' starts); only those whose
    # ordinate is within the cycles' can be inside one (the even–odd rule counts the segments
    # straddling it): a plate's face of a hundred holes tests the holes in the new one's row.
    polygons = X.polygons[f]
    first = np.cumsum([0, *map(len, polygons[:-1])]) if polygons else []
    probes = X.segments[f][first, 0] if polygons else np.zeros((0, 2))
    y = probes[:, 1]
    probes = probes[(y >= rings[:, :, 1].min()) & (y < rings[:, :, 1].max())]
    ok, area = _cycle_tests(rings, c0, size, probes)
    if not np.all(ok):
        return None
    per = rings.shape[1]  # ring points per use
    mids = rings.reshape(-1, 2)[c0 * per + (size * per) // 2]  # each ring's middle point
    if not np.all(_in_polygon(mids, X.segments[f], _slopes(X, f))):
        return None
    area = area * (1.0 if spec.sense else -1.0)
    if np.any(area == 0.0):
        return None
    # The pieces by the trusted constructors: the uses are the face's own and its (validated)
    # cuts, some reversed, in non-empty loops on the face's (validated) surface and sense.
    out_loops = list(spec.loops)
    islands = []
    for a, s, ar in zip(c0.tolist(), size.tolist(), area.tolist()):
        uses = [cuts[k] if fd else _reversed_use(cuts[k]) for k, fd in zip(order[a:a + s], fwd_l[a:a + s])]
        if ar < 0:
            uses = [_reversed_use(e) for e in reversed(uses)]
        islands.append(FaceSpec._trusted(spec.surface, spec.sense, (tuple(uses),)))
        out_loops.append(tuple(_reversed_use(e) for e in reversed(uses)))
    return [FaceSpec._trusted(spec.surface, spec.sense, tuple(out_loops))] + islands


def _fitted_end_near_loops(X: _Operand, f: int, cuts: list[EdgeSpec]) -> bool:
    """Whether :func:`_split_islands`' box test declines face ``f`` for the ends of its cuts with polynomial NURBS
    p-curves (fitted branches) alone: a branch crossing the face's boundary is told before the cuts are sampled.

    That test pads each cut's samples by their largest step plus ``1e-9 (1 + max |Q|)``.  The step is at least
    the chord between the ends over the ``_CLEAR_SAMPLES - 1`` steps, and ``max |Q|`` at least the ends'
    coordinates, so a box of half that lower bound about either end (the other half covers the round-off
    between scipy's B-spline, built for :func:`_clip`'s samples, and the samples' evaluation) lies inside the
    padded box: where it meets the box of a loop segment, so does the test's."""
    E = [c.pcurve._bspline(np.array([c.t0, c.t1])) for c in cuts
         if type(c.pcurve) is NurbsCurve and not c.pcurve.is_rational and c.pcurve.dimension == 2]
    if not E:
        return False
    E = np.stack(E)  # (m, 2 ends, 2)
    if not np.all(np.isfinite(E)):
        return False
    D = E[:, 1] - E[:, 0]
    pad = 0.5 * (row_norms(D) / (_CLEAR_SAMPLES - 1) + 1e-9 * (1.0 + np.max(np.abs(E), axis=(1, 2))))
    lo = (E - pad[:, None, None]).reshape(-1, 2)
    hi = (E + pad[:, None, None]).reshape(-1, 2)
    return _boxes_meet_2d(lo, hi, X.seg_lo[f], X.seg_hi[f])


def _middle_extremes(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Q.min(axis=1), Q.max(axis=1)`` of ``Q (n, s, d)``, coordinate by coordinate (the same values:
    numpy reduces the middle axis of a short last axis row by row, about ten times slower)."""
    lo = np.empty((Q.shape[0], Q.shape[2]))
    hi = np.empty((Q.shape[0], Q.shape[2]))
    for k in range(Q.shape[2]):
        lo[:, k], hi[:, k] = Q[:, :, k].min(axis=1), Q[:, :, k].max(axis=1)
    return lo, hi


def _cut_samples(cuts: list[EdgeSpec]) -> np.ndarray | None:
    """``(n, _CLEAR_SAMPLES, 2)`` samples of the cuts' p-curves at ``linspace(t0, t1)``, or None when a
    p-curve cannot be sampled so.

    ``Line2D`` and ``Trig2D`` p-curves (the cuts of planes and cylinders) all of a kind in one
    array pass (:func:`~coons.kernel.onsurface.curve_derivatives`, the p-curves' own expressions);
    others one by one.
    """
    T = linspace_rows([c.t0 for c in cuts], [c.t1 for c in cuts], _CLEAR_SAMPLES)
    try:
        return curve_derivatives([c.pcurve for c in cuts], T, 0, 2)[:, :, 0]
    except (CoonsError, ValueError, TypeError, AttributeError):
        return None


def _cut_ends(cuts: list[EdgeSpec]) -> np.ndarray:
    """``(2 n, 3)`` the cuts' 3-D end points (row ``2 k`` at ``t0``, ``2 k + 1`` at ``t1``), by
    :func:`~coons.kernel.onsurface.evaluate_curves`."""
    T = np.array([[c.t0, c.t1] for c in cuts])
    return evaluate_curves([c.curve for c in cuts], T).reshape(-1, 3)


def _boxes_meet_2d(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray,
                   skip_self: bool = False) -> bool:
    """Whether a closed box ``lo_a, hi_a (n, 2)`` meets one of ``lo_b, hi_b (m, 2)`` (another of the
    same set when ``skip_self``: then ``lo_b, hi_b`` are ``lo_a, hi_a``), by
    :func:`~coons.booleans._broad_phase.box_pairs` on flat 3-D boxes, or for one set of many boxes
    by :func:`_ring_box_pairs`' sort and sweep (the island cycles of a plate drilled in one call:
    a sort, where the trees cost about ten times more)."""
    if lo_a.shape[0] == 0 or lo_b.shape[0] == 0:
        return False
    if lo_a.shape[0] * lo_b.shape[0] <= _SMALL_BOX_PAIRS:  # (every pair costs less than building trees)
        # (coordinate by coordinate: numpy reduces a short last axis row by row)
        meet = lo_b[None, :, 0] <= hi_a[:, None, 0]
        meet &= hi_b[None, :, 0] >= lo_a[:, None, 0]
        meet &= lo_b[None, :, 1] <= hi_a[:, None, 1]
        meet &= hi_b[None, :, 1] >= lo_a[:, None, 1]
        if skip_self:
            np.fill_diagonal(meet, False)
        return bool(np.any(meet))
    if skip_self:
        return bool(_ring_box_pairs(lo_a, hi_a, np.zeros(lo_a.shape[0], dtype=np.int64))[0].size)
    z = np.zeros((1,))
    flat = [np.concatenate([x, np.broadcast_to(z, (x.shape[0], 1))], axis=1) for x in (lo_a, hi_a, lo_b, hi_b)]
    I, J = box_pairs(*flat)
    return bool(np.any(I != J)) if skip_self else bool(I.size)


#: Up to this many box pairs :func:`_boxes_meet_2d` tests every pair (a few cuts against a face of a
#: hundred holes' segments: the grid of ``box_pairs`` costs several times more).
_SMALL_BOX_PAIRS = 1 << 16


def _ring_box_pairs(lo: np.ndarray, hi: np.ndarray, ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(I, J)``, ``I < J``, of closed boxes ``lo, hi (N, 2)`` of one ring (``ring (N,)``, sorted) that meet.

    Sort and sweep along x within each ring: the boxes sorted by the key ``ring W + x`` (``W``
    wider than all boxes together, so rings follow each other), each box's candidates are those
    after it whose key is at most its upper key plus the key's rounding; the candidates are then
    tested exactly on both axes (and for one ring).  The sampled rings of holes meet few
    neighbours each: the cost is a sort, not the square of the ring's length.
    """
    N = lo.shape[0]
    if N < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    x0 = float(lo[:, 0].min())
    W = math.ceil(2.0 * (float(hi[:, 0].max()) - x0) + 1.0)
    base = ring.astype(np.float64) * W  # (exact: integers below 2^53)
    key_lo = base + (lo[:, 0] - x0)
    key_hi = base + (hi[:, 0] - x0)
    # (the keys round to a few units in the last place of the largest key: search that much further)
    slack = 4.0 * np.spacing(float(base[-1]) + W)
    order = np.argsort(key_lo, kind="stable")
    stop = np.searchsorted(key_lo[order], key_hi[order] + slack, side="right")
    count = np.maximum(stop - np.arange(N) - 1, 0)
    a = np.repeat(np.arange(N), count)
    b = a + 1 + (np.arange(a.size) - np.repeat(np.cumsum(count) - count, count))
    I, J = order[a], order[b]
    I, J = np.minimum(I, J), np.maximum(I, J)
    # (per coordinate, not np.all over the short last axis: numpy reduces it row by row)
    (lo_x, lo_y), (hi_x, hi_y) = lo.T, hi.T
    meet = ((ring[I] == ring[J]) & (lo_x[I] <= hi_x[J]) & (lo_x[J] <= hi_x[I])
            & (lo_y[I] <= hi_y[J]) & (lo_y[J] <= hi_y[I]))
    return I[meet], J[meet]


def _cycle_tests(rings: np.ndarray, c0: np.ndarray, size: np.ndarray, probes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per cycle, whether it is simple and holds none of ``probes``, and its signed area.

    ``rings (n, s, 2)``: each use's samples after its first, in traversal order; cycle ``c``
    is the uses ``c0[c] : c0[c] + size[c]``, its ring (closed polyline) their samples
    concatenated.  All cycles at once, on the flat array of all ring points: a proper crossing
    of two non-adjacent segments of one ring (:func:`~coons.kernel.polygon.proper_crossings`), on
    the pairs whose boxes meet (:func:`_ring_box_pairs`: two segments that cross share a point,
    so no crossing is missed, while testing every pair would cost the square of the ring's
    length); the probes (the first point of each of the face's loops) by the even–odd rule of
    :func:`~coons.booleans.classify._in_polygon` (its expressions), the crossings counted per
    ring; the area by :func:`_shoelace`'s terms summed per ring.

    Returns
    -------
    ok : (c,) bool
    area : (c,) float64
    """
    from coons.booleans.classify import _polygon_slopes

    nc, s = c0.size, rings.shape[1]
    P = rings.reshape(-1, 2)
    N = P.shape[0]
    start = c0 * s  # each ring's first point in P
    stop = (c0 + size) * s
    ring = np.repeat(np.arange(nc), size * s)
    nxt = np.arange(N) + 1
    nxt[stop - 1] = start
    A, B = P, P[nxt]  # segment p runs from P[p] to P[nxt[p]]
    I, J = _ring_box_pairs(np.minimum(A, B), np.maximum(A, B), ring)
    # Non-adjacent pairs of one ring (the first and last segments are adjacent).
    keep = (J > I + 1) & ~((I == start[ring[I]]) & (J == stop[ring[I]] - 1))
    I, J = I[keep], J[keep]
    ok = np.ones(nc, dtype=bool)
    ok[ring[I[proper_crossings(A[I], B[I], A[J], B[J])]]] = False
    if probes.shape[0]:
        seg = np.stack([A, B], axis=1)
        slope = _polygon_slopes(seg)
        x, y = probes[:, 0:1], probes[:, 1:2]
        straddle = (A[None, :, 1] > y) != (B[None, :, 1] > y)
        xc = A[None, :, 0] + (y - A[None, :, 1]) * slope[None, :]
        count = np.add.reduceat((straddle & (x < xc)).astype(np.int64), start, axis=1)  # (probes, rings)
        ok &= ~np.any(count % 2 == 1, axis=0)
    area = 0.5 * np.add.reduceat(A[:, 0] * B[:, 1] - B[:, 0] * A[:, 1], start)
    return ok, area


def _split_chords(X: _Operand, f: int, cuts: list[EdgeSpec], t: Tolerance,
                  prepared: dict[int, tuple | None] | None = None) -> list[FaceSpec] | None:
    """The pieces of face ``f`` when its cuts are straight chords across a straight-sided face, else None.

    The common case of a tool crossing a wall (a hole's half-cylinder cut by the two faces of
    the plate it passes through): the face lies on a plane or a cylinder and has one loop, every
    edge use and every cut has a ``Line2D`` p-curve (within ``tol.linear``), each cut runs from
    one side of the loop polygon to another, ending inside a side and crossing it at a sine of at
    least :data:`_STRAIGHT_MIN_SINE`, and the cuts keep more than :data:`_STRAIGHT_CLEARANCE`
    tolerances from each other, from the polygon's vertices and from every other side (in the
    isometric coordinates of :func:`_clip_straight`).  Each chord then splits the one region
    whose loop holds both its ends into two (the loop from one end to the other and the chord
    back), the sides split at the chords' ends (the exact crossing of two lines, whose 3-D
    points must agree with the cut's ends within the tolerances).  Anything else returns None
    (``split_face`` decides).

    The tests and the split parameters are :func:`_chord_data`'s, computed for all faces of an
    operand at once by ``_split`` (``prepared``) or here for this face alone.
    """
    if prepared is None:
        prepared = _chord_data(X, {f: cuts}, t)
    got = prepared.get(f)
    if got is None:
        return None
    ends, tau, SL, margin = got
    spec = X.specs[f]
    loop = spec.loops[0]
    n = len(cuts)
    ends_l, tau_l = ends.tolist(), tau.tolist()
    # The loop as (use, start node) items with every side split at its chord ends; node ids:
    # 2 k + which for chord ends, -1 for the loop's own vertices.
    at_side: dict[int, list[tuple[float, int]]] = {}
    for k in range(n):
        for w_ in (0, 1):
            at_side.setdefault(ends_l[k][w_], []).append((tau_l[k][w_], 2 * k + w_))
    # The pieces are made by the trusted constructor (no re-validation of the face's own curves
    # and tolerances) when their ranges are finite and non-empty, as the tests above make them;
    # else by the validating one, which raises as before.
    finite = all(math.isfinite(x) for pair in tau_l for x in pair)
    items: list[tuple[EdgeSpec, int]] = []
    for i, e in enumerate(loop):
        at = at_side.get(i, ())
        if len(at) > 1:  # (the sort and the spacing test only where a side holds several chord ends)
            at.sort(key=_first, reverse=e.t1 < e.t0)
            sl, dt = SL[i], abs(e.t1 - e.t0)
            for a, b in zip(at, at[1:]):
                if abs(a[0] - b[0]) * sl / dt <= margin:
                    return None
        make = (EdgeSpec._trusted if finite and (not at or (at[0][0] != e.t0 and at[-1][0] != e.t1))
                else EdgeSpec)
        prev, node = e.t0, -1
        for tt, nd in at:
            items.append((make(e.curve, prev, tt, e.pcurve, e.tol), node))
            prev, node = tt, nd
        items.append((make(e.curve, prev, e.t1, e.pcurve, e.tol), node))
    regions: list[list[tuple[EdgeSpec, int]]] = [items]
    for k, c in enumerate(cuts):
        p, q = 2 * k, 2 * k + 1
        for r, R in enumerate(regions):
            starts = [nd for _, nd in R]
            if p in starts or q in starts:
                break
        if p not in starts or q not in starts:
            return None
        i, j = starts.index(p), starts.index(q)
        path1 = R[i:j] if i < j else R[i:] + R[:j]
        path2 = R[j:i] if j < i else R[j:] + R[:i]
        back = _reversed_use(c)
        regions[r:r + 1] = [path1 + [(back, q)], path2 + [(c, p)]]
    # One non-empty loop of EdgeSpecs each, on the face's own (validated) surface and sense.
    return [FaceSpec._trusted(spec.surface, spec.sense, (tuple([e for e, _ in R]),)) for R in regions]


_first = operator.itemgetter(0)


def _chord_data(X: _Operand, cuts: dict[int, list[EdgeSpec]], t: Tolerance) -> dict[int, tuple | None]:
    """Per face of ``cuts`` (face -> its cuts), the tests of :func:`_split_chords` and where its sides split.

    Returns, per face, ``(ends, tau, SL, margin)`` when its cuts pass every test: ``ends (n, 2)``
    the side each chord end lies on (end ``which`` of cut ``k``), ``tau (n, 2)`` the side's
    curve parameter there (the foot of the cut's 3-D end on the side's curve), ``SL (m,)`` the
    sides' lengths and ``margin`` the clearance in the isometric coordinates; None otherwise.

    The faces that qualify by type (one loop on a plane or cylinder, every side and cut a
    ``Line2D``, sides within ``tol.linear``) are grouped by their numbers of sides and cuts, and
    each group is tested on stacked arrays with the expressions of the one-face tests (a plate
    drilled by 400 tools hands 800 half-cylinders of 4 sides and 2 chords to one pass); the
    feet on the sides' lines and circles are computed for all ends at once, by the curves'
    own ``closest_parameters`` and ``evaluate`` expressions (the stacked ``@`` rounds as theirs).
    """
    out: dict[int, tuple | None] = {}
    groups: dict[tuple[int, int], list[int]] = {}
    for f, cs in cuts.items():
        out[f] = None
        spec = X.specs[f]
        S = spec.surface
        if len(spec.loops) != 1 or not cs or not isinstance(S, (PlanarSurface, CylindricalSurface)):
            continue
        loop = spec.loops[0]
        if any(type(e.pcurve) is not Line2D or (e.tol or 0.0) > t.linear for e in loop) \
                or any(type(c.pcurve) is not Line2D for c in cs):
            continue
        groups.setdefault((len(loop), len(cs)), []).append(f)
    feet: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, float]] = []
    for (m, n), faces in groups.items():
        for f, ends, tau, SL, margin in zip(faces, *_chord_group(X, faces, cuts, m, n, t)):
            if ends is not None:
                feet.append((f, ends, tau, SL, margin))
    if feet:
        for (f, ends, tau, SL, margin), ok in zip(feet, _chord_feet(X, cuts, feet, t)):
            if ok:
                out[f] = (ends, tau, SL, margin)
    return out


def _chord_group(X: _Operand, faces: list[int], cuts: dict[int, list[EdgeSpec]], m: int, n: int, t: Tolerance):
    """The planar tests of :func:`_chord_data` for faces of ``m`` sides and ``n`` cuts, stacked (``F`` faces).

    Returns lists ``ends, tau, SL, margin`` per face, ``ends`` None where a test fails; ``tau``
    here is the plane solution, refined by :func:`_chord_feet`.
    """

    F = len(faces)
    specs = [X.specs[f] for f in faces]
    sp = np.array([[1.0, 1.0] if isinstance(s.surface, PlanarSurface) else [float(s.surface.radius), 1.0] for s in specs])
    sides = [e for s in specs for e in s.loops[0]]
    chords = [c for f in faces for c in cuts[f]]
    # Sides (m) and chords (n) as segments a + w (b - a), w in [0, 1], in isometric coordinates.
    O = np.array([e.pcurve.origin for e in sides]).reshape(F, m, 2)
    D = np.array([e.pcurve.direction for e in sides]).reshape(F, m, 2)
    T = np.array([[e.t0, e.t1] for e in sides]).reshape(F, m, 2)
    sa = (O + T[..., 0, None] * D) * sp[:, None, :]
    sb = (O + T[..., 1, None] * D) * sp[:, None, :]
    O = np.array([c.pcurve.origin for c in chords]).reshape(F, n, 2)
    D = np.array([c.pcurve.direction for c in chords]).reshape(F, n, 2)
    Tc = np.array([[c.t0, c.t1] for c in chords]).reshape(F, n, 2)
    ca = (O + Tc[..., 0, None] * D) * sp[:, None, :]
    cb = (O + Tc[..., 1, None] * D) * sp[:, None, :]
    scale = 1.0 + np.maximum(np.maximum(np.max(np.abs(sa), axis=(1, 2)), np.max(np.abs(ca), axis=(1, 2))),
                             np.max(np.abs(cb), axis=(1, 2)))
    ctol = np.array([c.tol or 0.0 for c in chords]).reshape(F, n).max(axis=1)
    margin = _STRAIGHT_CLEARANCE * np.maximum(t.linear, ctol) + 1e-12 * scale  # (F,)
    mg = margin[:, None]
    SE, CE = sb - sa, cb - ca
    SL, CL = np.hypot(SE[..., 0], SE[..., 1]), np.hypot(CE[..., 0], CE[..., 1])  # (F, m), (F, n)
    good = ~np.any(SL <= 2.0 * mg, axis=1) & ~np.any(CL <= 2.0 * mg, axis=1)
    # Chord–side crossings: (F, n, m) cross products and the fractions along both.
    W = sa[:, None] - ca[:, :, None]
    cross = CE[:, :, None, 0] * SE[:, None, :, 1] - CE[:, :, None, 1] * SE[:, None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        wc = (W[..., 0] * SE[:, None, :, 1] - W[..., 1] * SE[:, None, :, 0]) / cross  # along the chord
        ws = (W[..., 0] * CE[:, :, None, 1] - W[..., 1] * CE[:, :, None, 0]) / cross  # along the side
    # Each chord end: exactly one side within the margin of it, crossed properly there, away
    # from the side's ends (all 2 n ends against all m sides at once; end 2 k + which).
    P = np.stack([ca, cb], axis=2).reshape(F, 2 * n, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.clip(np.einsum("femj,fmj->fem", P[:, :, None, :] - sa[:, None], SE) / (SL * SL)[:, None, :], 0.0, 1.0)
    dist = np.hypot(*np.moveaxis(P[:, :, None, :] - sa[:, None] - w[..., None] * SE[:, None], -1, 0))
    near = dist <= mg[:, :, None]
    good &= np.all(near.sum(axis=2) == 1, axis=1)
    side = np.argmax(near, axis=2)  # (F, 2n)
    fi = np.arange(F)[:, None]
    kk = np.repeat(np.arange(n), 2)[None, :]
    cr, wsi = cross[fi, kk, side], ws[fi, kk, side]
    SLs = SL[fi, side]
    with np.errstate(invalid="ignore"):
        good &= np.all(np.abs(cr) >= _STRAIGHT_MIN_SINE * CL[fi, kk] * SLs, axis=1) & np.all(np.isfinite(wsi), axis=1)
        good &= np.all((wsi * SLs > mg) & ((1.0 - wsi) * SLs > mg), axis=1)  # else at or near a vertex
    t_0, t_1 = T[fi, side, 0], T[fi, side, 1]
    tau = (t_0 + wsi * (t_1 - t_0)).reshape(F, n, 2)
    ends = side.reshape(F, n, 2)
    # Away from its end sides a chord meets no side, and no vertex comes near it.
    inner = np.ones((F, n, m), dtype=bool)
    inner[np.arange(F)[:, None, None], np.arange(n)[None, :, None], ends] = False
    lo, hi = -1e-12, 1.0 + 1e-12
    with np.errstate(invalid="ignore"):
        good &= ~np.any((wc >= lo) & (wc <= hi) & (ws >= lo) & (ws <= hi) & inner, axis=(1, 2))
    segs = np.stack([ca, cb], axis=2)  # (F, n, 2, 2)
    good &= ~np.any(_segment_distances(sa, segs) <= mg[:, :, None], axis=(1, 2))
    # Chords apart from each other: no chord end near another chord, no proper crossing.
    if n > 1:
        d_end = _segment_distances(P, segs)  # (F, 2n, n)
        d_end[:, np.arange(2 * n), np.repeat(np.arange(n), 2)] = np.inf  # (a chord's own ends)
        good &= ~np.any(d_end <= mg[:, :, None], axis=(1, 2))
        i, j = _index_pairs(n)
        c = CE[:, i, 0] * CE[:, j, 1] - CE[:, i, 1] * CE[:, j, 0]
        Dc = ca[:, j] - ca[:, i]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (Dc[..., 0] * CE[:, j, 1] - Dc[..., 1] * CE[:, j, 0]) / c
            y = (Dc[..., 0] * CE[:, i, 1] - Dc[..., 1] * CE[:, i, 0]) / c
        with np.errstate(invalid="ignore"):
            good &= ~np.any((c != 0.0) & (x >= 0.0) & (x <= 1.0) & (y >= 0.0) & (y <= 1.0), axis=1)
    g = good.tolist()
    return ([ends[k] if g[k] else None for k in range(F)], list(tau), list(SL), margin.tolist())


@functools.lru_cache(maxsize=64)
def _index_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)`` (read-only): the pairs ``i < j`` of ``n`` chords, made once per ``n`` (numpy
    builds them through a mask, several times the cost of the few chords' tests)."""
    i, j = np.triu_indices(n, 1)
    i.setflags(write=False)
    j.setflags(write=False)
    return i, j


def _segment_distances(Q: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """``(F, k, s)`` distances of points ``Q (F, k, 2)`` to segments ``seg (F, s, 2, 2)``, face by face,
    with the expressions of :func:`~coons.booleans.classify._segment_distance` (which keeps the minimum)."""
    a = seg[:, :, 0]
    d = seg[:, :, 1] - a
    dd = np.maximum(np.einsum("fij,fij->fi", d, d), 1e-300)[:, None, :]
    R = [Q[:, :, None, i] - a[:, None, :, i] for i in range(2)]
    lam = (R[0] * d[:, None, :, 0] + R[1] * d[:, None, :, 1]) / dd
    np.clip(lam, 0.0, 1.0, out=lam)
    return np.sqrt(np.square(R[0] - lam * d[:, None, :, 0]) + np.square(R[1] - lam * d[:, None, :, 1]))


def _chord_feet(X: _Operand, cuts: dict[int, list[EdgeSpec]], feet: list, t: Tolerance) -> list[bool]:
    """Move each chord end's split parameter to the foot of the cut's 3-D end on the side's curve.

    The split parameters are those of the cut ends' feet on the side's 3-D curve (the face
    across that edge finds the same from the same point, so its split matches exactly), and
    must agree with the plane solution.  ``feet`` holds ``(face, ends, tau, SL, margin)``
    entries; each ``tau`` is updated in place.  Returns per entry whether every end passes (a
    side that is not a line or circle fails).  All ends at once: lines and circles by their
    ``closest_parameters`` and ``evaluate`` expressions on stacked arrays.
    """
    from coons.kernel.analytic import _angle

    # One row per chord end (row 2 k + which of the entries' cuts in order): its side use, the
    # plane solution, the side's length, the margin and the entry it belongs to.
    uses: list[EdgeSpec] = []
    chords: list[EdgeSpec] = []
    for f, ends, _, _, _ in feet:
        loop = X.specs[f].loops[0]
        uses += [loop[i] for i in ends.ravel().tolist()]
        chords += cuts[f]
    R = len(uses)
    per = np.array([2 * ends.shape[0] for _, ends, _, _, _ in feet])
    entry = np.repeat(np.arange(len(feet)), per)
    tau0 = np.concatenate([tau.ravel() for _, _, tau, _, _ in feet])
    SLr = np.concatenate([SL[ends].ravel() for _, ends, _, SL, _ in feet])
    mg = np.repeat([margin for *_, margin in feet], per)
    # The cuts' 3-D ends (each cut evaluated at both ends, as the cut's own two-point call would), once
    # per cut: its two rows (ends 0 and 1) follow each other.
    Pc = evaluate_curves([c.curve for c in chords], np.array([[c.t0, c.t1] for c in chords])).reshape(R, 3)
    x = tau0.copy()
    sides = [e.curve for e in uses]
    kinds = [type(c) for c in sides]
    lines = [r for r, k in enumerate(kinds) if k is Line]
    circles = [r for r, k in enumerate(kinds) if k is Circle]
    Pe = Pc.copy()  # (the feet in space; rows that fail keep the cut's end: they are dropped anyway)
    if lines:
        Ol = np.array([sides[r].origin for r in lines])
        Dl = np.array([sides[r].direction for r in lines])
        x[lines] = ((Pc[lines] - Ol)[:, None, :] @ Dl[:, :, None])[:, 0, 0]
        # (Line.evaluate's expression on the rows gathered here: the same floats as evaluate_curves')
        Pe[lines] = Ol + x[lines][:, None] * Dl
    if circles:
        Oc = np.array([sides[r]._origin for r in circles])
        Fc = np.array([sides[r]._frame for r in circles])
        L = ((Pc[circles] - Oc)[:, None, :] @ np.swapaxes(Fc, 1, 2))[:, 0, :]
        # into the use's period
        x[circles] = [a + math.remainder(b - a, 2.0 * math.pi)
                      for a, b in zip(tau0[circles].tolist(), _angle(L[:, 1], L[:, 0]).tolist())]
    ok = [True] * len(feet)
    others = []  # (rows on subclasses of Line and Circle, by their own methods)
    if len(lines) + len(circles) < R:
        for r, (c, k) in enumerate(zip(sides, kinds)):
            if k is Line or k is Circle:
                continue
            if not isinstance(c, (Line, Circle)):
                ok[int(entry[r])] = False
                continue
            xr = float(np.asarray(c.closest_parameters(Pc[r][None]), dtype=np.float64).reshape(-1)[0])
            x[r] = tau0[r] + math.remainder(xr - tau0[r], 2.0 * math.pi) if isinstance(c, Circle) else xr
            others.append(r)
    rest = circles + others
    if rest:
        Pe[rest] = evaluate_curves([sides[r] for r in rest], x[rest][:, None])[:, 0]
    T = np.array([(e.t0, e.t1, e.tol or 0.0) for e in uses])
    span = np.abs(T[:, 1] - T[:, 0])
    thr = np.maximum(np.maximum(t.linear, np.repeat([c.tol or 0.0 for c in chords], 2)), T[:, 2])
    bad = (np.abs(x - tau0) * SLr / span > mg) | (row_norms(Pe - Pc) > thr)
    for q in entry[bad].tolist():
        ok[q] = False
    r = 0
    for f, ends, tau, SL, margin in feet:
        n = ends.shape[0]
        tau[:] = x[r:r + 2 * n].reshape(n, 2)
        r += 2 * n
    return ok


def _self_crossing(seg: np.ndarray) -> bool:
    """Whether two non-adjacent segments of a closed polyline ``(m, 2, 2)`` cross properly (touching is not
    tested): :func:`~coons.kernel.polygon.proper_crossings` of every pair, the reference of :func:`_cycle_tests`' boxed pairs."""
    m = seg.shape[0]
    i, j = np.triu_indices(m, 2)
    keep = ~((i == 0) & (j == m - 1))
    i, j = i[keep], j[keep]
    return bool(np.any(proper_crossings(seg[i, 0], seg[i, 1], seg[j, 0], seg[j, 1])))


def _distance_to_edges(X: _Operand, f: int, Q: np.ndarray, t: Tolerance, others: list[EdgeSpec] = ()
                       ) -> np.ndarray:
    """Distances ``(k,)`` of the points ``Q (k, 3)`` to face ``f``'s boundary edges and the edges ``others``."""
    return _loop_distances(X, f, Q, t, others).min(axis=1)


def _loop_distances(X: _Operand, f: int, Q: np.ndarray, t: Tolerance, others: list[EdgeSpec] = ()
                    ) -> np.ndarray:
    """Distances ``(k, L + 1)`` of the points ``Q (k, 3)`` to the edges of each of face ``f``'s ``L`` loops and,
    last, to the edges ``others`` (``inf`` where there are none)."""
    from coons.booleans.classify import _curve_closest

    loops = (*X.specs[f].loops, others)
    best = np.full((Q.shape[0], len(loops)), np.inf)
    for k, loop in enumerate(loops):
        for e in loop:
            lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
            tq = np.clip(_curve_closest(e.curve, Q, lo, t), lo, hi)
            d = np.linalg.norm(np.asarray(e.curve.evaluate(tq)).reshape(-1, 3) - Q, axis=1)
            best[:, k] = np.minimum(best[:, k], d)
    return best


def _along_edges(X: _Operand, f: int, c: EdgeSpec, others: list[EdgeSpec], t: Tolerance,
                 span: tuple[float, float]) -> bool:
    """Whether cut ``c`` over ``span`` of its parameter lies within ten times its tolerance of face ``f``'s
    boundary or of the cuts ``others`` at :data:`_ALONG_SAMPLES` points, ends included: ``split_face`` drops
    such a stretch (the other edge serves)."""
    Q = np.asarray(c.curve.evaluate(np.linspace(*span, _ALONG_SAMPLES)), dtype=np.float64).reshape(-1, 3)
    return bool(np.all(_distance_to_edges(X, f, Q, t, others) <= 10.0 * max(t.linear, c.tol or 0.0)))


def _short_of_two(spans: list[tuple[float, float]], lo: float, hi: float, eps: float) -> list[tuple[float, float]]:
    """The stretches of ``[lo, hi]`` longer than ``eps`` that fewer than two of the ranges ``spans`` cover."""
    cuts = sorted({lo, hi, *(x for a, b in spans for x in (a, b) if lo < x < hi)})
    out: list[tuple[float, float]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        m = 0.5 * (a + b)
        if b - a > eps and sum(1 for u, v in spans if u <= m <= v) < 2:
            if out and out[-1][1] == a:
                out[-1] = (out[-1][0], b)
            else:
                out.append((a, b))
    return out


#: Points of a dropped cut tested against its face's boundary and other cuts (:func:`_along_edges`).
_ALONG_SAMPLES = 17


def _free_chains(X: _Operand, f: int, cuts: list[EdgeSpec], t: Tolerance) -> np.ndarray:
    """Per cut, whether its chain (cuts joined end to end) separates nothing: it has an end inside the face
    (not on its boundary), or it bridges loops of the face that neither the boundary nor the chains
    before it join already (a line of tangent contact from a hole's edge to the outer edge).

    ``split_face`` drops such chains whole (both sides are one region); a chain from a loop back to
    the loops it joins closes a cycle and separates two regions.  A cut that never leaves the ball
    of its own tolerance is a point, as sewing collapses it into its vertex (a tangent section
    clipped to a sliver shorter than its end tolerance): the cut ends within that ball meet there,
    and the point's own ends are no chain's end nor a neighbour that makes another cut's end a joint.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(cuts)
    E = np.array([np.asarray(c.curve.evaluate(np.array([c.t0, c.t1])), dtype=np.float64) for c in cuts]).reshape(-1, 3)
    thr = np.repeat([max(t.linear, c.tol or 0.0) for c in cuts], 2)
    D = np.linalg.norm(E[:, None] - E[None], axis=-1)
    close = D <= np.maximum(thr[:, None], thr[None])
    point = np.array([not _long_enough(c.curve, min(c.t0, c.t1), max(c.t0, c.t1), t, float(thr[2 * k]))
                      for k, c in enumerate(cuts)])
    for d in np.flatnonzero(point).tolist():
        near = D[2 * d] <= thr[2 * d]
        close |= near[:, None] & near[None, :]
    real = ~np.repeat(point, 2)
    degree = close[:, real].sum(axis=1) - real  # other cut ends at this end, points not counted
    i, j = np.nonzero(close)
    g = coo_matrix((np.ones(i.size), (i // 2, j // 2)), shape=(n, n))
    _, comp = connected_components(g, directed=False)
    ends = np.flatnonzero((degree == 0) & real)
    on_boundary = np.zeros(ends.size, dtype=bool)
    loop = np.zeros(ends.size, dtype=np.int64)
    if ends.size:
        L = _loop_distances(X, f, E[ends], t)[:, :-1]
        loop = np.argmin(L, axis=1)
        on_boundary = L[np.arange(ends.size), loop] <= 10.0 * thr[ends]
    free_comp = np.zeros(comp.max() + 1, dtype=bool)
    free_comp[comp[ends[~on_boundary] // 2]] = True
    # Chains with every end on the boundary, in order: a bridge joins loops not yet joined (union-find).
    joined = list(range(len(X.specs[f].loops)))

    def root(a: int) -> int:
        while joined[a] != a:
            a = joined[a]
        return a

    chain_of = comp[ends[on_boundary] // 2]
    for c in np.unique(chain_of).tolist():
        if free_comp[c]:
            continue
        loops_c = loop[on_boundary][chain_of == c].tolist()
        roots = {root(k) for k in loops_c}
        if len(roots) == len(loops_c) > 1:  # every end on a loop not joined to another end's: a bridge
            first, *rest = roots
            for r in rest:
                joined[r] = first
            free_comp[c] = True
    return free_comp[comp]


def _check_cuts_used(X: _Operand, f: int, cuts: list[EdgeSpec], pieces: list[FaceSpec], t: Tolerance) -> None:
    """Each cut must bound two pieces (once each way): its range covered twice by the pieces' uses of its curve.

    ``split_face`` drops cuts it finds dangling; a cut dropped although it belongs to a path
    across the face would leave the face unsplit and the result open, so it raises here.

    Raises
    ------
    BooleanError
        (stage ``"split"``) naming the face and the first cut not used twice.
    """
    spans = _curve_spans(pieces)
    free = None
    for k, c in enumerate(cuts):
        lo, hi = min(c.t0, c.t1), max(c.t0, c.t1)
        eps = 1e-9 * (1.0 + abs(lo) + abs(hi))  # parameter rounding of sub-ranges
        covered = sum(b - a for a, b in spans.get(id(c.curve), []) if a >= lo - eps and b <= hi + eps)
        if covered < 2.0 * (hi - lo) - 1e-6 * (hi - lo) - eps:
            # Used fewer than twice: legitimate for a dangling tree dropped whole (a line of tangent
            # contact ending inside the face), and where the stretches not used twice run along the
            # face's boundary or another cut, which serves instead (a sliver of a section touching a
            # sphere face's boundary meridian, clipped to that face and again, overlapping, to its
            # neighbour; a section osculating such a meridian over its first stretch); not for a path
            # whose ends all lie on the face's boundary or that closes.
            if abs(covered) <= 1e-6 * (hi - lo) + eps:
                if free is None:
                    free = _free_chains(X, f, cuts, t)
                if free[k]:
                    continue
            short = _short_of_two(spans.get(id(c.curve), []), lo, hi, eps)
            others = [o for o in cuts if o is not c]
            if short and all(_along_edges(X, f, c, others, t, span) for span in short):
                continue
        if abs(covered - 2.0 * (hi - lo)) > 1e-6 * (hi - lo) + eps:
            P = np.asarray(c.curve.evaluate(np.array([c.t0, c.t1]))).tolist()
            raise BooleanError(
                f"operand {X.name}, face {f} ({_kind(X.specs[f])}): cut {k} from {P[0]} to {P[1]} bounds the "
                f"pieces for {covered / (hi - lo):.3g} times its length; expected 2 (one piece on each side): "
                "split_face dropped or duplicated it",
                stage="split", diagnostics={"operand": X.name, "face": f, "cut": k, "ends": P,
                                            "coverage": covered / (hi - lo)})


# ---------------------------------------------------------------------- classify
def _unpaired(n: int, idx: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: faces in no broad-phase pair (their boxes meet no face box of the other operand)."""
    free = np.ones(n, dtype=bool)
    free[idx] = False
    return free


def _classify(pieces: list[tuple[int, FaceSpec]], X: _Operand, Y: _Operand, t: Tolerance,
              free: np.ndarray | None = None, cuts: dict[int, list[EdgeSpec]] | None = None,
              links: dict[int, list[_Link]] | None = None, side: int = 0,
              local: np.ndarray | None = None) -> np.ndarray:
    """Status of every piece of X with respect to solid Y (``(k,)`` int8 of OUT/IN/ON_SAME/ON_OPPOSITE).

    ``local``: the statuses the local way (1 below) gave, -1 where it gave none, when the caller
    found them already (:func:`_local_both`, both operands in one pass); the local way is then
    not run again.

    Four ways, cheapest first (the module docstring, phase 5):

    0. *Far*: a piece of a face whose box lies outside Y's box is OUT.
    1. *Local*: a piece bounded by a cut along a transversal stretch of a branch inside both
       faces of its pair (``links``, :func:`_intersect`; ``side`` 0 when X is A, 1 when X is B)
       takes its side from the first-order geometry at a point ``q`` of that cut
       (:func:`_local_status`): IN when the direction into the piece, ``N_X × T``, points
       against Y's outward normal there.
    2. *Propagated*: a piece of a face in ``free`` (no broad-phase pair: the face and its edges
       are farther from Y's boundary than the boxes' padding) takes the status of a piece across
       one of its edges (the same curve object over an overlapping range), found so far: near
       that edge both lie on the same side of Y.
    3. *By a point*: the rest by :func:`_classify_points`, against Y's classifier.

    Raises
    ------
    BooleanError
        (stage ``"classify"``) no interior point found, or a point on an edge of Y (the piece
        should have been split there).
    """
    status = np.full(len(pieces), -1, dtype=np.int8) if local is None else local.copy()
    y_boxed = len(Y.specs) and bool(np.all(np.isfinite(Y.lo) & np.isfinite(Y.hi) & (Y.lo <= Y.hi)))
    if free is not None and len(pieces) and y_boxed:
        # A face whose box lies outside Y's box is outside Y: most faces of a large part cut by
        # a small tool, decided by one array test instead of one by one (only when every face
        # of Y has a proper box, so that their union holds Y).
        valid = np.all(np.isfinite(X.lo) & np.isfinite(X.hi) & (X.lo <= X.hi), axis=1)
        far = np.any((X.lo > Y.hi.max(axis=0)) | (X.hi < Y.lo.min(axis=0)), axis=1) & free & valid
        status[far[np.fromiter((f for f, _ in pieces), dtype=np.int64, count=len(pieces))]] = OUT
    if links and cuts and local is None:
        _local_status(pieces, Y, links, side, t, status, cut=cuts)
    if free is not None:
        _propagate(pieces, free, status)
    rest = np.flatnonzero(status < 0)
    if rest.size:
        dangling = _dangling_cuts(pieces, cuts or {})
        status[rest] = _classify_points([pieces[k] for k in rest.tolist()], rest.tolist(), X, Y, t, free, dangling)
    return status


#: Smallest ``|sin|`` of the angle between the direction into a piece and the other solid's
#: tangent plane at a cut for the local test (:func:`_local_status`); shallower cuts (near
#: tangency) are classified by a point.
_LOCAL_SIN = 1e-2
#: The local test's point must lie this many tolerances clear of the other face's boundary (its
#: padded segment boxes), so that the face is the other solid's whole boundary near it.
_LOCAL_CLEARANCE = 10.0


def _local_status(pieces: list[tuple[int, FaceSpec]], Y: _Operand, links: dict[int, list[_Link]], side: int,
                  t: Tolerance, status: np.ndarray, cut: dict | None = None) -> None:
    """Fill ``status`` of the pieces bounded by a linked cut (see :func:`_classify`, way 1).

    For a cut edge use of a piece over a range overlapping a link's, ``q = C(s)`` at the middle
    of the overlap lies inside the piece's face and inside face ``Y_j`` of the link.  Loops run
    counter-clockwise about the outward normal (``docs/brep.md``), so ``d = N_X × T`` (``T`` the
    tangent in the use's direction) points into the piece; when ``|d · N_Y| >= _LOCAL_SIN`` the
    surfaces cross there and the piece lies inside Y near ``q`` iff ``d · N_Y < 0``, and a piece
    lies wholly on one side.  ``q`` must also be clear of ``Y_j``'s loops (its parameter lies
    outside the padded boxes of the loop segments, enlarged by :data:`_LOCAL_CLEARANCE`
    tolerances), where Y's boundary near ``q`` is ``Y_j`` alone.  Pieces with no such cut keep -1.
    A piece takes its first candidate use that passes: the candidates are tested in rounds of
    one per undecided piece (:func:`_local_tests`, each round in one array pass: a plate's face with
    a hundred hole discs is one evaluation).  ``cut``
    (when given) holds the faces that were split: only their pieces have cut edges.
    """
    _local_status_many([(pieces, Y, side, status, cut)], links, t)


def _local_both(pieces_a: list[tuple[int, FaceSpec]], pieces_b: list[tuple[int, FaceSpec]], A: _Operand,
                B: _Operand, cuts_a: dict, cuts_b: dict, links: dict[int, list[_Link]],
                t: Tolerance) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The statuses the local way gives the pieces of A (against B) and of B (against A), -1 where it
    gives none (:func:`_local_status`), both operands' rounds tested together (:func:`_local_tests`:
    one array pass per round instead of one per operand; a box minus a cylinder has one round of
    a few candidates on each side).  None for an operand without cuts (or without links), as
    :func:`_classify` then runs no local way."""
    jobs = []
    out: list[np.ndarray | None] = [None, None]
    for side, (pieces, Y, cuts) in enumerate(((pieces_a, B, cuts_a), (pieces_b, A, cuts_b))):
        if links and cuts:
            out[side] = np.full(len(pieces), -1, dtype=np.int8)
            jobs.append((pieces, Y, side, out[side], cuts))
    if jobs:
        _local_status_many(jobs, links, t)
    return out[0], out[1]


def _local_status_many(jobs: list[tuple], links: dict[int, list[_Link]], t: Tolerance) -> None:
    """:func:`_local_status` of several ``(pieces, Y, side, status, cut)`` at once: each round tests the
    next candidate of every undecided piece of every job in one :func:`_local_tests` pass."""
    # Each piece takes its first candidate that passes (in the order of its loops and uses): evaluated in
    # rounds of one candidate per undecided piece, as a piece bounded by a hundred hole circles needs one
    # of them, not all; each piece's candidates are found as its rounds come (most pieces need one).
    # (the undecided pieces as (job, generator), in order; a round's answers written per job in one step)
    active = [(j, _piece_candidates(k, f, spec, links, side))
              for j, (pieces, _, side, status, cut) in enumerate(jobs)
              for k, ((f, spec), open_) in enumerate(zip(pieces, (status < 0).tolist()))
              if open_ and (cut is None or f in cut)]
    while active:
        sub, of, waiting = [], [], []
        for j, gen in active:
            c = next(gen, None)
            if c is not None:
                sub.append(c)
                of.append(j)
                waiting.append((j, gen))
        if not sub:
            return
        Ys = jobs[0][1] if len(jobs) == 1 else [jobs[j][1] for j in of]
        ok, cos = _local_tests(sub, Ys, t)
        piece = np.fromiter((c[0] for c in sub), dtype=np.int64, count=len(sub))
        job = np.asarray(of, dtype=np.int64)
        answer = np.where(cos < 0, IN, OUT)
        for j, (_, _, _, status, _) in enumerate(jobs):
            done = ok & (job == j)
            status[piece[done]] = answer[done]
        active = [x for x, good in zip(waiting, ok.tolist()) if not good]


def _piece_candidates(k: int, f: int, spec: FaceSpec, links: dict[int, list[_Link]], side: int):
    """The local test's candidates ``(piece, spec, use, s, face of Y, p-curve on it)`` of piece ``k`` (of face
    ``f``), in the order of its loops, uses and links (:func:`_local_status`): a generator, read as far as the
    piece's rounds go."""
    for loop in spec.loops:
        for e in loop:
            got = links.get(id(e.curve))
            if got is None:
                continue
            lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
            for ln in got:
                a, b = max(lo, ln.s0), min(hi, ln.s1)
                if ln.faces[side] == f and b > a:
                    yield (k, spec, e, 0.5 * (a + b), ln.faces[1 - side], ln.pcurves[1 - side])


def _local_tests(cand: list[tuple], Y: "_Operand | list[_Operand]", t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """The local test of :func:`_local_status` for candidates ``(piece, spec, use, s, face of Y,
    p-curve on it)``: ``(k,)`` whether it applies and the cosine whose sign decides (IN when
    negative).  All candidates in one pass: lines, arcs, planes and surfaces of revolution in one
    expression per type, other curves and surfaces one call per object.  ``Y``: the other operand
    of every candidate, or a list of each one's (:func:`_local_status_many`: both operands' pieces
    in one pass); the answers are per candidate, whatever else is in the pass."""
    n = len(cand)
    Ys = Y if isinstance(Y, list) else [Y] * n
    ops = {id(y): y for y in Ys}
    # (the candidates' fields as columns, in one pass)
    _, specs, uses, s, faces, pcurves_y = zip(*cand)
    s = np.array(s)
    ok = np.ones(n, dtype=bool)
    T, uv_x, uv_y = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros((n, 2))
    n_x = np.zeros((n, 3))

    def batched(objects: list, compute, out: np.ndarray) -> None:
        """``out[r] = compute(objects[r], r)`` for all rows in one call (lines, arcs, planes and
        surfaces of revolution in one expression per type); when that fails, per object, the
        rows of a failing one not ok."""
        try:
            out[:] = compute(objects, slice(None))
            return
        except (CoonsError, ValueError, ArithmeticError):
            pass
        groups: dict[int, list[int]] = {}
        for i, obj in enumerate(objects):
            groups.setdefault(id(obj), []).append(i)
        for rows in groups.values():
            r = np.asarray(rows)
            try:
                out[r] = compute([objects[rows[0]]] * r.size, r)
            except (CoonsError, ValueError, ArithmeticError):
                ok[r] = False

    frame = np.zeros((n, 2, 2, 3))
    batched([e.curve for e in uses], lambda objs, r: curve_derivatives(objs, s[r, None], 1, 3)[:, 0, 1], T)
    batched([e.pcurve for e in uses], lambda objs, r: curve_derivatives(objs, s[r, None], 0, 2)[:, 0, 0], uv_x)
    batched(list(pcurves_y), lambda objs, r: curve_derivatives(objs, s[r, None], 0, 2)[:, 0, 0], uv_y)
    batched([f.surface for f in specs], lambda objs, r: surface_normals(objs, uv_x[r, 0], uv_x[r, 1]), n_x)
    face_y = [y.specs[j] for j, y in zip(faces, Ys)]
    batched([f.surface for f in face_y], lambda objs, r: surface_derivatives(objs, uv_y[r, 0], uv_y[r, 1], 1), frame)
    Su, Sv = frame[:, 1, 0], frame[:, 0, 1]
    forward = np.array([e.t1 > e.t0 for e in uses])
    sense_x = np.array([1.0 if f.sense else -1.0 for f in specs])
    sense_y = np.array([1.0 if f.sense else -1.0 for f in face_y])
    T = np.where(forward[:, None], T, -T)
    # (np.cross's products and np.linalg.norm's sums written out: the same floats, without the set-up of
    # either or numpy's row-by-row reduction of a short axis)
    d = _cross(sense_x[:, None] * n_x, T)
    n_y = _cross(Su, Sv)
    sd, sn = row_norms(d), row_norms(n_y)
    su, sv = row_norms(Su), row_norms(Sv)
    speed = np.stack([su, sv], axis=1)
    # (column by column: numpy's all() over a short last axis runs row by row)
    ok &= ((sd > 0) & (sn > 0) & (su > 0) & (sv > 0) & np.isfinite(d[:, 0]) & np.isfinite(d[:, 1])
           & np.isfinite(d[:, 2]) & np.isfinite(sn))
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = sense_y * np.einsum("ij,ij->i", d, n_y) / (sd * sn)
        ok &= np.abs(cos) >= _LOCAL_SIN
        # Clear of Y_j's loops: outside every padded segment box enlarged by the clearance in the
        # parameter plane (a space distance over the surface's speeds there).
        m = _LOCAL_CLEARANCE * np.array([max(t.linear, e.tol or 0.0) for e in uses])[:, None] / speed
    # (the faces of Y by (operand, face))
    by_face: dict[tuple[int, int], list[int]] = {}
    for i in np.flatnonzero(ok).tolist():
        by_face.setdefault((id(Ys[i]), faces[i]), []).append(i)
    # Faces of few loops: every candidate against every padded segment box of its face, all such
    # faces in one pass over the (candidate, segment) pairs (a hundred holes' walls).
    few = [(y, j) for y, j in by_face if len(ops[y].specs[j].loops) <= _LOOPS_BOXED]
    few = [(y, j) for y, j in few if ops[y].seg_lo[j].shape[0]]  # (a face without segments: no box to be near)
    if few:
        r = np.array([i for key in few for i in by_face[key]], dtype=np.int64)
        nseg = np.array([ops[y].seg_lo[j].shape[0] for y, j in few], dtype=np.int64)
        per_row = np.repeat(nseg, [len(by_face[key]) for key in few])  # each row's face's segment count
        seg0 = np.repeat(np.cumsum(nseg) - nseg, [len(by_face[key]) for key in few])  # and its first segment
        pair_start = np.cumsum(per_row) - per_row
        row = np.repeat(np.arange(r.size), per_row)
        seg = np.repeat(seg0 - pair_start, per_row) + np.arange(int(per_row.sum()))
        lo = np.concatenate([ops[y].seg_lo[j] for y, j in few])
        hi = np.concatenate([ops[y].seg_hi[j] for y, j in few])
        q, mr = uv_y[r], m[r]
        # (coordinate by coordinate, each gathered as a column: numpy's fancy index of the rows of an
        # (n, 2) array and its all() over that short last axis run row by row)
        near = np.ones(seg.size, dtype=bool)
        for ax in (0, 1):
            qa, ma = q[:, ax][row], mr[:, ax][row]
            near &= (qa >= lo[:, ax][seg] - ma) & (qa <= hi[:, ax][seg] + ma)
        ok[r[np.logical_or.reduceat(near, pair_start)]] = False
    for (y, j), rows in by_face.items():
        Y = ops[y]
        if len(Y.specs[j].loops) <= _LOOPS_BOXED:
            continue  # (above)
        r = np.asarray(rows)
        q, mr = uv_y[r], m[r]
        # Only the segments of loops whose box comes near a point (a plate's face of many holes).
        first, llo, lhi = _loop_boxes(Y._data[j], Y.specs[j])
        loops = np.flatnonzero(_points_near_boxes(q, mr, llo, lhi).any(axis=0))
        if loops.size == 0:
            continue
        seg = _loop_segment_rows(first, Y.seg_lo[j].shape[0], loops)
        ok[r[_points_near_boxes(q, mr, Y.seg_lo[j][seg], Y.seg_hi[j][seg]).any(axis=1)]] = False
    return ok, cos


def _points_near_boxes(q: np.ndarray, m: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(n, b)`` bool: whether the point ``q[i]`` lies in the box ``[lo[j], hi[j]]`` enlarged by its margins
    ``m[i]`` (all ``(·, 2)``); coordinate by coordinate (numpy's all() over a short last axis runs row by row)."""
    near = np.ones((q.shape[0], lo.shape[0]), dtype=bool)
    for ax in (0, 1):
        qa, ma = q[:, ax, None], m[:, ax, None]
        near &= (qa >= lo[None, :, ax] - ma) & (qa <= hi[None, :, ax] + ma)
    return near


#: Faces of more loops than this have their points tested against the segments of the loops whose
#: box comes near only (:func:`_loop_boxes`).
_LOOPS_BOXED = 8


def _loop_boxes(d: "_FaceData", spec: FaceSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(first, lo, hi)``: per loop of the face ``spec`` (its data ``d``), its first segment in
    ``d.seg_lo`` and the union ``(L, 2)`` of its segments' padded boxes (a face's loops in order, as
    ``_face_data`` stacks them); computed once per face data.

    A loop's union is its :class:`_LoopData`'s ``seg_min, seg_max`` columns (the same reduction over the
    same rows in the same order).  The rows of the loops that the last face boxed here with the same first
    use had first (:data:`_LOOP_BOXES`) are taken in one piece: a plate's top gaining a hole every cut
    stacks only its new loop's."""
    if d.loop_boxes is None:
        loops = d.loops
        n0 = 0
        got = _LOOP_BOXES.get(spec.loops[0][0])
        if got is not None:
            old, first0, lo0, hi0 = got
            n0 = len(old)
            if n0 > len(loops) or not all(map(operator.is_, old, loops[:n0])):
                n0 = 0
        new = loops[n0:]
        count = np.array([ld.seg_lo.shape[0] for ld in new], dtype=np.int64)
        rows = _loop_rows(new) if new else np.zeros((0, 16))
        lo, hi = rows[:, _LOOP_COLUMNS["seg_min"]], rows[:, _LOOP_COLUMNS["seg_max"]]
        first = np.cumsum(count) - count
        if n0:
            first = np.concatenate([first0, first + (first0[-1] + loops[n0 - 1].seg_lo.shape[0])])
            lo, hi = np.concatenate([lo0, lo]), np.concatenate([hi0, hi])
        d.loop_boxes = (_frozen(first), _frozen(lo), _frozen(hi))
        _LOOP_BOXES.set(spec.loops[0][0], (tuple(loops), *d.loop_boxes))
    return d.loop_boxes


#: First use of a face -> ``(its loops' :class:`_LoopData`, first, lo, hi of :func:`_loop_boxes`)`` of
#: the last face data boxed with that first use.  The value never holds the key (loop data holds a
#: loop's uses after the first).
_LOOP_BOXES = IdentityMemo()


def _propagate(pieces: list[tuple[int, FaceSpec]], free: np.ndarray, status: np.ndarray) -> None:
    """Give unclassified pieces of free faces the status of a classified piece across an edge (:func:`_classify`, way 2).

    A breadth-first search from the classified pieces over the free ones; two pieces are
    neighbours when they use the same curve object over overlapping ranges.
    """
    targets: dict[int, list[tuple[float, float, int]]] = {}  # curve id -> (lo, hi, piece) of unclassified free uses
    for k, (f, spec) in enumerate(pieces):
        if free[f] and status[k] < 0:
            for loop in spec.loops:
                for e in loop:
                    targets.setdefault(id(e.curve), []).append((min(e.t0, e.t1), max(e.t0, e.t1), k))
    if not targets:
        return
    queue = np.flatnonzero(status >= 0).tolist()
    while queue:
        k = queue.pop()
        for loop in pieces[k][1].loops:
            for e in loop:
                got = targets.get(id(e.curve))
                if not got:
                    continue
                lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
                for a, b, k2 in got:
                    if status[k2] < 0 and min(hi, b) > max(lo, a):
                        status[k2] = status[k]
                        queue.append(k2)


def _classify_points(pieces: list[tuple[int, FaceSpec]], ids: list[int], X: _Operand, Y: _Operand, t: Tolerance,
                     free: np.ndarray | None, dangling: dict[int, list[EdgeSpec]]) -> np.ndarray:
    """Status of pieces by one point each against Y's classifier (:func:`_classify`, way 3).

    ``ids`` are the pieces' numbers among all pieces of X (for the messages).

    Each piece is classified by an interior point (:func:`_interior_point`) clear of its
    boundary and of the cuts of its face that bound no piece (``dangling``): the lines of
    tangent contact with Y that ``split_face`` dropped, on which the point would be *on* Y.

    A piece of a face in ``free`` is classified by any of its points, its first vertex,
    instead of a searched interior point; all such pieces still go through the classifier in
    the one vectorised call, and should one of them come out on Y's boundary, it is redone with
    an interior point.
    """
    from coons.booleans.classify import INSIDE, ON

    P = np.empty((len(pieces), 3))
    N = np.empty((len(pieces), 3))
    quick = np.zeros(len(pieces), dtype=bool)

    def avoid_of(f: int, spec: FaceSpec) -> np.ndarray | None:
        if f not in dangling:
            return None
        try:
            return np.concatenate([_polyline_segments(_edge_uv(c, spec.surface, _LOOP_SAMPLES)) for c in dangling[f]])
        except CoonsError:
            return None  # (interior() raises it with the piece named)

    def interior(k: int, f: int, spec: FaceSpec) -> None:
        try:
            avoid = None
            if f in dangling:
                avoid = np.concatenate([_polyline_segments(_edge_uv(c, spec.surface, _LOOP_SAMPLES)) for c in dangling[f]])
            P[k], N[k] = _interior_point(spec, t, avoid)
        except CoonsError as exc:
            raise BooleanError(f"operand {X.name}, piece {ids[k]} of face {f}: {exc}", stage="classify",
                               diagnostics={"operand": X.name, "face": f, "piece": ids[k]}) from exc

    searched = []
    for k, (f, spec) in enumerate(pieces):
        if free is not None and free[f]:
            e = spec.loops[0][0]
            P[k] = np.asarray(e.curve.evaluate(e.t0), dtype=np.float64).reshape(3)
            N[k] = np.nan
            quick[k] = True
        else:
            searched.append(k)
    # The first grid of every searched piece in array passes; the pieces it leaves open alone.
    found = _interior_points([(pieces[k][1], avoid_of(*pieces[k])) for k in searched], t)
    for k, got in zip(searched, found):
        if got is None:
            interior(k, *pieces[k])
        else:
            P[k], N[k] = got
    cls, normal = Y.classifier.classify(P)
    redo = np.flatnonzero(quick & (cls == ON))
    if redo.size:  # not expected: a free face's vertex on Y's boundary
        for k in redo.tolist():
            interior(k, *pieces[k])
        cls[redo], normal[redo] = Y.classifier.classify(P[redo])
    status = np.where(cls == INSIDE, IN, OUT).astype(np.int8)
    on = np.flatnonzero(cls == ON)
    if on.size:
        bad = on[~np.all(np.isfinite(normal[on]), axis=1)]
        if bad.size:
            k = int(bad[0])
            raise BooleanError(
                f"operand {X.name}, piece {ids[k]} of face {pieces[k][0]}: its interior point {P[k].tolist()} lies on "
                f"an edge of operand {Y.name}; expected the piece to be split there",
                stage="classify", diagnostics={"operand": X.name, "face": pieces[k][0], "piece": ids[k],
                                               "point": P[k].tolist()})
        same = np.einsum("ij,ij->i", N[on], normal[on]) > 0.0
        status[on] = np.where(same, ON_SAME, ON_OPPOSITE)
    return status


def _curve_spans(pieces: list[FaceSpec]) -> dict[int, list[tuple[float, float]]]:
    """``id(curve) -> [(lo, hi), ...]``: the parameter ranges of every use of each curve by the pieces."""
    spans: dict[int, list[tuple[float, float]]] = {}
    for p in pieces:
        for loop in p.loops:
            for e in loop:
                spans.setdefault(id(e.curve), []).append((min(e.t0, e.t1), max(e.t0, e.t1)))
    return spans


def _dangling_cuts(pieces: list[tuple[int, FaceSpec]], cuts: dict[int, list[EdgeSpec]]) -> dict[int, list[EdgeSpec]]:
    """Per face, the cuts that no piece of it uses along any part of their range (dropped by the split)."""
    of_face: dict[int, list[FaceSpec]] = {}
    for f, p in pieces:
        if f in cuts:
            of_face.setdefault(f, []).append(p)
    out: dict[int, list[EdgeSpec]] = {}
    for f, cs in cuts.items():
        spans = _curve_spans(of_face.get(f, []))
        for c in cs:
            lo, hi = min(c.t0, c.t1), max(c.t0, c.t1)
            if not any(a < hi and b > lo for a, b in spans.get(id(c.curve), ())):
                out.setdefault(f, []).append(c)
    return out


def _polyline_segments(R: np.ndarray) -> np.ndarray:
    """The segments ``(k - 1, 2, 2)`` of an open polyline ``(k, 2)``."""
    return np.stack([R[:-1], R[1:]], axis=1)


def _interior_point(spec: FaceSpec, t: Tolerance, avoid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A point of the piece's interior away from its boundary, and the outward normal there.

    The candidates are a grid over the parameter box of the trim polygon, ``n × (n + 2)`` for
    ``n`` = 16, 64, 256 in turn; the one inside farthest from the polygon and from the segments
    ``avoid`` wins, distances measured with the surface's first fundamental form at the box
    centre, provided it is more than ``_INTERIOR_CLEARANCE · tol.linear`` from them (else the
    next grid is tried).  The two even counts keep grid points off the box's centre lines and
    diagonals: a piece cut by a straight chord between two corners of its box (a circular
    segment) has its chord on a diagonal, where an ``n × n`` grid would put candidates exactly
    on it and the in-polygon test and the classifier that follows would be decided by rounding.

    Parameters
    ----------
    spec : FaceSpec
    t : Tolerance
    avoid : (m, 2, 2) array of float, optional
        Parameter-plane segments inside the piece to keep clear of as of its boundary: the
        intersection curves that end inside the face (a line of tangent contact), along which
        a point would be *on* the other solid.  On a periodic surface they are also taken one
        period to either side.

    Raises
    ------
    InvalidInputError
        No grid point lies inside the trim polygon clear of its boundary (a sliver thinner
        than the finest grid).
    """
    from coons.booleans.classify import _in_polygon, _segment_distance

    S, seg, near, lo, hi, scale = _interior_setup(spec, avoid)
    clearance = _INTERIOR_CLEARANCE * t.linear
    for n in (16, 64, 256):
        G = _interior_grid(lo, hi, n)
        G = G[_in_polygon(G, seg)]
        if G.shape[0]:
            if G.shape[0] * near.shape[0] > _EXACT_DISTANCES:
                d = _boundary_distance(G * scale, near * scale, n)
            else:
                d = _segment_distance(G * scale, near * scale)
            best = int(np.argmax(d))
            if d[best] <= clearance:
                continue
            return _interior_at(spec, G[best])
    raise InvalidInputError(f"no interior point found in a {_kind(spec)} piece with parameter box {lo.tolist()}–{hi.tolist()} "
                            f"farther than {clearance:.3g} from its boundary")


def _interior_setup(spec: FaceSpec, avoid: np.ndarray | None):
    """What :func:`_interior_point` searches with: ``(surface, seg (s, 2, 2), near (m, 2, 2), lo, hi, scale)``:
    the trim segments, those and the segments to avoid, the parameter box and the metric scale."""
    S = spec.surface
    rings = _loop_rings(spec)  # (the samples of the uses a piece keeps from its face are cached)
    seg = np.concatenate([np.stack([R, np.roll(R, -1, axis=0)], axis=1) for R in rings])
    U = np.concatenate(rings)
    lo, hi = U.min(axis=0), U.max(axis=0)
    c = 0.5 * (lo + hi)
    D = np.asarray(S.derivatives(c[0], c[1], 1))
    scale = np.array([np.linalg.norm(D[1, 0]), np.linalg.norm(D[0, 1])])
    scale = np.where(scale > 0, scale, 1.0)
    near = seg
    if avoid is not None and len(avoid):
        shifts = [np.array([du, dv]) for du in _period_steps(S, "period_u") for dv in _period_steps(S, "period_v")]
        near = np.concatenate([seg] + [avoid + d for d in shifts])
    return S, seg, near, lo, hi, scale


def _interior_grid(lo: np.ndarray, hi: np.ndarray, n: int) -> np.ndarray:
    """The ``n × (n + 2)`` candidate grid ``(n (n + 2), 2)`` over the box, u-major (as ``meshgrid(..., indexing="ij")``)."""
    gu, gv = _grid_fractions(n)
    G = np.empty((n * (n + 2), 2))
    G[:, 0] = np.repeat(lo[0] + gu * (hi[0] - lo[0]), n + 2)
    G[:, 1] = np.tile(lo[1] + gv * (hi[1] - lo[1]), n)
    return G


def _interior_at(spec: FaceSpec, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    S = spec.surface
    P = np.asarray(S.evaluate(uv[0], uv[1]), dtype=np.float64).reshape(3)
    nrm = np.asarray(S.normal(uv[0], uv[1]), dtype=np.float64).reshape(3)
    return P, (nrm if spec.sense else -nrm)


#: Pieces with more trim segments than this take their first grid alone (the row sweep of
#: ``_in_polygon``, a k-d tree for the distances) instead of in the batched array passes.
_BATCH_SEGMENTS = 512
#: Point–segment pairs held at once by the batched passes of :func:`_interior_points` (memory bound).
_BATCH_PAIRS = 1 << 20


def _interior_points(items: list[tuple[FaceSpec, np.ndarray | None]], t: Tolerance) -> list:
    """The first grid (``n`` = 16) of :func:`_interior_point` for many pieces at once.

    Returns, per item ``(spec, avoid)``, the point and normal :func:`_interior_point` returns, or
    None where it must be asked alone (its first grid finds no point clear of the boundary, the
    piece has many segments, or setting it up raises).  Pieces with the same number of trim
    segments (all the hole walls of a plate, all its discs) are tested against their own
    segments in one array pass, as are their distances; every element is the same
    floating-point expression as in :func:`~coons.booleans.classify._in_polygon` (all pairs)
    and :func:`~coons.booleans.classify._segment_distance`, so the chosen grid point is the same.
    """
    n = 16
    clearance = _INTERIOR_CLEARANCE * t.linear
    out: list = [None] * len(items)
    _prefill_samples([spec for spec, _ in items])
    setup: dict[int, tuple] = {}
    by_count: dict[int, list[int]] = {}
    for k, (spec, avoid) in enumerate(items):
        try:
            S, seg, near, lo, hi, scale = _interior_setup(spec, avoid)
        except CoonsError:
            continue  # (asked alone, the piece raises with its name)
        if seg.shape[0] > _BATCH_SEGMENTS:
            continue
        setup[k] = (seg, near, scale, _interior_grid(lo, hi, n))
        by_count.setdefault(seg.shape[0], []).append(k)
    inside: dict[int, np.ndarray] = {}
    g = n * (n + 2)
    for s, ks in by_count.items():
        step = max(1, _BATCH_PAIRS // (g * s))
        for b0 in range(0, len(ks), step):
            kb = ks[b0 : b0 + step]
            seg = np.stack([setup[k][0] for k in kb])  # (p, s, 2, 2)
            G = np.stack([setup[k][3] for k in kb])  # (p, g, 2)
            a, c = seg[:, :, 0], seg[:, :, 1]
            dy = c[..., 1] - a[..., 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                slope = (c[..., 0] - a[..., 0]) / np.where(dy == 0, 1.0, dy)
            x, y = G[..., 0:1], G[..., 1:2]
            straddle = (a[:, None, :, 1] > y) != (c[:, None, :, 1] > y)
            xc = a[:, None, :, 0] + (y - a[:, None, :, 1]) * slope[:, None, :]
            odd = (np.count_nonzero(straddle & (x < xc), axis=2) % 2) == 1
            for k, m in zip(kb, odd):
                inside[k] = setup[k][3][m]
    # Distances, grouped by (points inside, segments to keep clear of).
    by_shape: dict[tuple[int, int], list[int]] = {}
    for k, Gk in inside.items():
        near = setup[k][1]
        if Gk.shape[0] == 0 or Gk.shape[0] * near.shape[0] > _EXACT_DISTANCES:
            continue  # (no point inside, or the k-d tree of _boundary_distance: asked alone)
        by_shape.setdefault((Gk.shape[0], near.shape[0]), []).append(k)
    for (q, m), ks in by_shape.items():
        step = max(1, _BATCH_PAIRS // (q * m))
        for b0 in range(0, len(ks), step):
            kb = ks[b0 : b0 + step]
            Q = np.stack([inside[k] * setup[k][2] for k in kb])  # (p, q, 2)
            seg = np.stack([setup[k][1] * setup[k][2] for k in kb])  # (p, m, 2, 2)
            a = seg[:, :, 0]
            d = seg[:, :, 1] - a
            dd = np.stack([np.maximum(np.einsum("ij,ij->i", dk, dk), 1e-300) for dk in d])  # as _segment_distance
            R = [Q[:, :, None, i] - a[:, None, :, i] for i in range(2)]  # (p, q, m) per coordinate
            lam = sum(R[i] * d[:, None, :, i] for i in range(2)) / dd[:, None, :]
            np.clip(lam, 0.0, 1.0, out=lam)
            d2 = sum(np.square(R[i] - lam * d[:, None, :, i]) for i in range(2))
            dist = np.sqrt(np.min(d2, axis=2))  # (p, q)
            for k, dk in zip(kb, dist):
                best = int(np.argmax(dk))
                if dk[best] > clearance:
                    try:
                        out[k] = _interior_at(items[k][0], inside[k][best])
                    except CoonsError:
                        pass  # (asked alone)
    return out


@functools.lru_cache(maxsize=None)
def _grid_fractions(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell-centre fractions of the interior-point grid: ``(n,)`` along u and ``(n + 2,)`` along v (read-only)."""
    return _frozen((np.arange(n) + 0.5) / n), _frozen((np.arange(n + 2) + 0.5) / (n + 2))


def _period_steps(S, name: str) -> tuple[float, ...]:
    """``(0,)``, or ``(-p, 0, p)`` when S has the period ``p`` in that parameter."""
    per = getattr(S, name, None)
    return (-per, 0.0, per) if per else (0.0,)


#: An interior point must be this many linear tolerances from its piece's boundary: nearer, the
#: classifier would call it *on* the other solid wherever the boundary is an intersection curve.
_INTERIOR_CLEARANCE = 10.0


#: Above this many point–segment pairs, the interior point's distances to the boundary are
#: taken from a k-d tree of boundary samples (a face with many holes) instead of every segment.
_EXACT_DISTANCES = 20000


def _boundary_distance(G: np.ndarray, seg: np.ndarray, n: int) -> np.ndarray:
    """Approximate distances ``(k,)`` of points ``G (k, 2)`` to segments ``seg (s, 2, 2)``.

    The segments are sampled at spacing ``h`` (1/n of the larger box side, the grid's own
    resolution) and the distance to the nearest sample, less ``h / 2``, is returned: it is
    within ``h / 2`` of the exact one, which is all the choice of a point far from the boundary
    needs.
    """
    from scipy.spatial import cKDTree

    a, b = seg[:, 0], seg[:, 1]
    lo, hi = seg.reshape(-1, 2).min(axis=0), seg.reshape(-1, 2).max(axis=0)
    h = max(float(np.max(hi - lo)) / n, 1e-300)
    length = np.linalg.norm(b - a, axis=1)
    k = np.maximum(1, np.ceil(length / h).astype(np.int64))
    which = np.repeat(np.arange(seg.shape[0]), k)
    frac = (np.arange(which.size) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
    pts = a[which] + frac[:, None] * (b - a)[which]
    d, _ = cKDTree(pts).query(G)
    return d - 0.5 * h


# ---------------------------------------------------------------------- select
def _select(op: str, pieces_a, status_a: np.ndarray, pieces_b, status_b: np.ndarray) -> list[FaceSpec]:
    keep_a, keep_b, flip = _TABLE[op]
    out = [spec for (f, spec), s in zip(pieces_a, status_a.tolist()) if s in keep_a]
    for (f, spec), s in zip(pieces_b, status_b.tolist()):
        if s in keep_b:
            out.append(reversed_face(spec) if flip else spec)
    return out


def reversed_face(spec: FaceSpec) -> FaceSpec:
    """The face with the opposite orientation: sense flipped, each loop reversed with its uses' ``t0, t1`` swapped."""
    # (the trusted constructors: a FaceSpec's loops are already non-empty tuples of validated EdgeSpecs
    # and its sense a bool, so the validating ones would only copy them again; a Boolean reverses every
    # kept face of its tool: a plate's hundred hole walls)
    loops = tuple(tuple([_reversed_use(e) for e in reversed(loop)]) for loop in spec.loops)
    if type(spec) is not FaceSpec:  # (a stand-in from a caller of this public function: validated)
        return FaceSpec(spec.surface, not spec.sense, loops)
    return FaceSpec._trusted(spec.surface, not spec.sense, loops)


def _reversed_use(e: EdgeSpec) -> EdgeSpec:
    """The use ``e`` run the other way (``t0, t1`` swapped), by the trusted constructor: ``e`` is a
    validated EdgeSpec, so its fields are already what validation makes of them."""
    return EdgeSpec._trusted(e.curve, e.t1, e.t0, e.pcurve, e.tol)


# ---------------------------------------------------------------------- T-junctions
def _split_edges_at_vertices(faces: list[FaceSpec], t: Tolerance, orig: dict | None = None,
                             orig_edges: tuple | None = None, boxes: dict | None = None) -> list[FaceSpec]:
    """Split every edge use at the end points of other uses lying inside it (T-junctions).

    A cut ending on a boundary edge of one face splits that edge there (``split_face``), but the
    face across the edge may have received no cut (its other side touches the other operand only
    along the edge: a sphere's meridian lying in a box face).  Sewing needs both uses of an edge
    to have the same vertices, so every vertex of the selected faces that lies on the interior
    of an edge use (within the edges' tolerance, parameter strictly inside) splits it.

    ``orig`` maps ``id(face)`` of faces passed through unchanged to ``(operand 1 or 2, index)`` and
    ``boxes`` (given with ``orig``) each operand to its faces' padded space boxes ``(lo, hi)``, ``(F, 3)``
    each; ``orig_edges`` gives the operand of edge uses passed through unchanged (also inside split
    faces): ``(ids, order, operand)``, :func:`~coons.topology._memo.id_index` of those uses and the
    operand of each (the first found of a use listed twice).  A vertex belongs to the operand of the
    edge use it starts (0 for new ones); an unchanged face or edge use is only tested against the
    vertices of the other operand and new ones (a valid solid has no vertex inside its own
    edges), and skipped when none lies in its box: after many cuts a plate's faces keep hundreds
    of untouched hole edges.  Faces without split edges are returned as the same objects.
    """
    from coons.booleans.classify import _curve_closest

    orig = orig or {}
    if not faces:
        return faces
    # The uses' points, ranges and curve ids (per face spec, cached; a result's faces from its sewing's
    # columns in one take: sew._gathered_uses).
    (points, ranges, curve_id, spec), _, count = _gathered_uses(faces, ("points", "ranges", "curve_id", "spec"))
    starts = points[:, 0]
    # A vertex is as uncertain as the widest tolerance of the uses meeting there.
    use_tol = np.maximum(ranges[:, 2], t.linear)
    start_tol = _cluster_max(starts, use_tol)
    first = np.concatenate([[0], np.cumsum(count)])
    # An unchanged face or edge use of an operand can only meet vertices not of that operand
    # (a valid solid has no vertex inside its own edges): 0 new, 1 of A, 2 of B.  Every use of
    # an unchanged face is an unchanged use of its operand.
    info_of = [orig.get(id(f)) for f in faces]
    group = np.repeat(np.array([0 if i is None else i[0] for i in info_of], dtype=np.int64), count)
    # (the uses of the other faces found by id, all at once)
    is_new = np.array([i is None for i in info_of], dtype=bool)
    other = np.repeat(is_new, count)
    if orig_edges is not None and orig_edges[0].size and other.any():
        at, found = found_by_id(spec[other], orig_edges[0], orig_edges[1])
        group[other] = np.where(found, orig_edges[2][at], 0)
    foreign_of = {g: (starts[group != g], start_tol[group != g]) for g in (1, 2)}
    # The foreign vertices in the box of each unchanged face (after many cuts most faces of a
    # plate are unchanged and far from the new vertices; :func:`_foreign_in_boxes`).
    kept = [k for k, i in enumerate(info_of) if i is not None]
    face_foreign: dict[int, np.ndarray] = {}
    if kept:
        # (the pairs flattened: numpy reads a list of tuples slowly)
        g_of, f_of = np.fromiter(itertools.chain.from_iterable(info_of[k] for k in kept), dtype=np.int64,
                                 count=2 * len(kept)).reshape(-1, 2).T
        for g in (1, 2):
            sel = np.flatnonzero(g_of == g)
            foreign = np.flatnonzero(group != g)
            if sel.size and foreign.size:
                lo, hi = boxes[g][0][f_of[sel]], boxes[g][1][f_of[sel]]
                for k, inside in zip(sel.tolist(), _foreign_in_boxes(lo, hi, starts, start_tol, foreign)):
                    if inside.size:
                        face_foreign[kept[k]] = inside
    # Which uses of which faces a vertex may split (:func:`_clear_uses`), then the candidate
    # vertices of all those uses in one pass (:func:`_shared_candidates`).  A new face's new uses
    # are never clear (every vertex is foreign to them): a new face without a use of an operand (a
    # cut cylinder's pieces) is open throughout without a test.
    is_open = other.copy()  # (an unchanged face is clear throughout unless tested below)
    n_operand = np.diff(np.concatenate([[0], np.cumsum(group != 0)])[first])  # (per face, its operand uses)
    tested = sorted(set(face_foreign) | set(np.flatnonzero(is_new & (n_operand > 0)).tolist()))
    for k in tested:
        f = faces[k]
        inside = face_foreign.get(k)
        near = None if inside is None else (starts[inside], start_tol[inside])
        sl = slice(int(first[k]), int(first[k + 1]))
        # (a face of many loops, as a plate's top gaining a hole, boxes only the uses the last one had not)
        is_open[sl] = ~_clear_uses([e for loop in f.loops for e in loop], group[sl], use_tol[sl], near, foreign_of,
                                   kept=len(f.loops) > _PREFIX_LOOPS)
    open_rows = np.flatnonzero(is_open)
    if open_rows.size == 0:
        return faces
    # (the open uses' keys for _shared_candidates from the use tables: curve ids, ranges)
    found = _shared_candidates(spec[open_rows].tolist(), starts, start_tol, t,
                               (curve_id[open_rows], *ranges[open_rows].T))
    if not found:
        return faces  # no vertex near the interior of any open use (T-junctions are few)
    # Only the faces of an open use with a candidate may change; their uses are walked by row.
    hits = {int(open_rows[i]): got for i, got in found.items()}
    busy = np.unique(np.searchsorted(first, list(hits), side="right") - 1).tolist()
    out = list(faces)
    changed_any = False
    for k in busy:
        f = faces[k]
        row = itertools.count(int(first[k]))
        loops = []
        face_changed = False
        for loop in f.loops:
            new: list[EdgeSpec] = []
            for e in loop:
                got = hits.get(next(row))
                if got is None:
                    new.append(e)  # (clear, or no candidate vertex)
                    continue
                X, cand = got
                thr = max(t.linear, e.tol or 0.0)
                params: list[float] = []
                Q, qt = starts[cand], np.maximum(start_tol[cand], thr)
                lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
                tq = _curve_closest(e.curve, Q, lo, t)
                on = (tq > lo) & (tq < hi)
                if np.any(on):
                    d = np.linalg.norm(np.asarray(e.curve.evaluate(tq[on])) - Q[on], axis=1)
                    params = sorted({float(x) for x in tq[on][d <= qt[on]]}, reverse=e.t1 < e.t0)
                if not params:
                    new.append(e)
                    continue
                # Several vertices within tolerance of one point split once.
                knots = [e.t0]
                last = X[0]
                for x, P in zip(params, np.asarray(e.curve.evaluate(np.asarray(params))).reshape(-1, 3)):
                    if np.linalg.norm(P - last) > thr and np.linalg.norm(P - X[-1]) > thr:
                        knots.append(x)
                        last = P
                knots.append(e.t1)
                face_changed = face_changed or len(knots) > 2
                for a, b in zip(knots[:-1], knots[1:]):
                    if a != b:
                        new.append(EdgeSpec(e.curve, a, b, e.pcurve, e.tol))
            loops.append(new)
        if face_changed:
            out[k] = FaceSpec(f.surface, f.sense, loops)
            changed_any = True
    return out if changed_any else faces


def _shared_candidates(open_uses: list[EdgeSpec], starts: np.ndarray, start_tol: np.ndarray, t: Tolerance,
                       keys: tuple[np.ndarray, ...] | None = None) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """:func:`_split_candidates` then :func:`_off_the_ends` of ``open_uses``, each distinct edge computed
    once: per open use (by its position) that has a candidate vertex, its samples ``(17, 3)`` in its own
    direction and its candidates (indices into ``starts``); the uses without any are left out (most:
    T-junctions are few).

    The two uses of an edge (one per face, opposite ways round) share their samples and candidates: each
    distinct (curve, range, tolerance) is sampled and queried once, in the way its first use runs; the
    other use reads the samples backwards (the end samples are the curve at the range's ends either way;
    the inner ones only place the query's ball, which bounds the range whichever way it is sampled). The
    key holds all a use's candidates depend on (its curve, range and tolerance; the rest is the call's):
    should the search ever read more of a use (its face, its operand group), the key must too.

    ``keys``: the uses' ``(id(curve), t0, t1, tol or 0)`` as arrays ``(k,)`` when the caller has them (the
    T-junction pass reads them from the use tables, :class:`~coons.topology.sew._FaceUses`), else read from
    the uses.  The distinct keys are found by one sort (float keys compare as Python's do: ``0.0 == -0.0``).
    """
    n = len(open_uses)
    if keys is None:
        keys = (np.array([id(e.curve) for e in open_uses], dtype=np.int64).reshape(n),
                np.array([e.t0 for e in open_uses], dtype=np.float64).reshape(n),
                np.array([e.t1 for e in open_uses], dtype=np.float64).reshape(n),
                np.array([e.tol or 0.0 for e in open_uses], dtype=np.float64).reshape(n))
    ids, t0, t1, tol = keys
    first, of = row_groups(ids, np.minimum(t0, t1), np.maximum(t0, t1), tol)
    distinct = [open_uses[i] for i in first.tolist()]
    # (max(t.linear, tol) as the uses give it: numpy's fmax, like Python's max here, keeps t.linear over a NaN)
    ranges = (t0[first], t1[first], np.fmax(tol[first], t.linear))
    X_u, cand_u = _split_candidates(distinct, starts, t, ranges)
    use, vertex = _off_the_ends(X_u, cand_u, starts, start_tol, ranges[2])  # (symmetric in the two ends)
    if use.size == 0:
        return {}
    bounds = np.searchsorted(use, np.arange(len(distinct) + 1)).tolist()  # (the pairs come use by use)
    has = np.zeros(len(distinct), dtype=bool)
    has[use] = True
    out = {}
    for i in np.flatnonzero(has[of]).tolist():
        u = int(of[i])
        X = X_u[u] if t0[i] == t0[first[u]] else X_u[u, ::-1]  # (a use running the other way from its group's first)
        out[i] = (X, vertex[bounds[u]:bounds[u + 1]])
    return out


def _split_candidates(uses: list[EdgeSpec], starts: np.ndarray, t: Tolerance,
                      ranges: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, list]:
    """For each use, its curve at 17 parameters ``(k, 17, 3)`` and the indices of ``starts``
    within the ball around those samples (their centre, the largest distance to it times
    1.05 plus the use's tolerance: chords of 16 steps deviate little).  Lines and circles are
    evaluated together (:func:`~coons.kernel.onsurface.evaluate_curves`, their own formulas),
    and all balls are one k-d tree query.  ``ranges``: the uses' :func:`_use_ranges` when the
    caller has them."""
    from scipy.spatial import cKDTree

    from coons.kernel.onsurface import evaluate_curves

    t0, t1, thr = _use_ranges(uses, t) if ranges is None else ranges
    T = np.linspace(t0, t1, 17, axis=1)
    X = evaluate_curves([e.curve for e in uses], T)
    c = X.mean(axis=1)
    D = X - c[:, None, :]
    # Coordinate-wise (a norm over the short last axis is several times slower; same sums in the same order).
    rad = np.sqrt(D[..., 0] * D[..., 0] + D[..., 1] * D[..., 1] + D[..., 2] * D[..., 2]).max(axis=1)
    r = rad * 1.05 + thr
    if len(uses) * starts.shape[0] > _BALL_PAIRS:
        return X, cKDTree(starts).query_ball_point(c, r)
    return X, _in_balls(c, r, starts)


def _use_ranges(uses: list[EdgeSpec], t: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The uses' ``t0``, ``t1`` and tolerance ``max(t.linear, tol or 0)`` (that of the T-junction pass), ``(k,)``
    each."""
    k = len(uses)
    return (np.fromiter((e.t0 for e in uses), dtype=np.float64, count=k),
            np.fromiter((e.t1 for e in uses), dtype=np.float64, count=k),
            np.fromiter((max(t.linear, e.tol or 0.0) for e in uses), dtype=np.float64, count=k))


#: Up to this many ball–point pairs :func:`_split_candidates` tests every pair (a sequential cut's few
#: open uses against all of a plate's vertices: building the tree cost more than the whole test).
_BALL_PAIRS = 1 << 15


def _in_balls(c: np.ndarray, r: np.ndarray, P: np.ndarray) -> list[np.ndarray]:
    """Per ball ``c[i] (3,), r[i]``, the indices of the points ``P (n, 3)`` within it, ascending: what
    ``cKDTree(P).query_ball_point(c, r)`` gives, by the test its leaves make (the squared distance
    summed over the coordinates in order, against ``r²``) on every pair."""
    d2 = P[None, :, 0] - c[:, 0, None]
    d2 *= d2
    for j in (1, 2):
        dj = P[None, :, j] - c[:, j, None]
        d2 += dj * dj
    rows, cols = np.nonzero(d2 <= (r * r)[:, None])
    # (each ball's slice of cols: np.split's set-up costs more on a sequential cut's few balls)
    ends = np.searchsorted(rows, np.arange(c.shape[0] + 1)).tolist()
    return [cols[a:b] for a, b in zip(ends[:-1], ends[1:])]


def _off_the_ends(X: np.ndarray, cand: list, starts: np.ndarray, start_tol: np.ndarray,
                  thr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The candidate vertices of uses (indices into ``starts``, from :func:`_split_candidates`)
    farther than ``max(their tolerance, the use's thr)`` from both of the use's ends ``X[:, 0]``,
    ``X[:, -1]``: only those can split it.  All pairs in one pass (most candidates are the
    use's own end vertices), kept as pairs ``(use, vertex)``, ``(m,)`` each: use by use
    (ascending), each use's vertices in the order of ``cand``."""
    n = np.fromiter((len(c) for c in cand), dtype=np.int64, count=len(cand))
    flat = np.fromiter(itertools.chain.from_iterable(cand), dtype=np.int64, count=int(n.sum()))
    use = np.repeat(np.arange(len(cand)), n)
    Q, qt = starts[flat], np.maximum(start_tol[flat], thr[use])
    keep = (np.linalg.norm(Q - X[use, 0], axis=1) > qt) & (np.linalg.norm(Q - X[use, -1], axis=1) > qt)
    return use[keep], flat[keep]


def _clear_uses(edges: list[EdgeSpec], group: np.ndarray, thr: np.ndarray, face_foreign, foreign_of: dict,
                kept: bool = False) -> np.ndarray:
    """``(k,)`` bool: which of a face's edge uses no vertex can split (see :func:`_split_edges_at_vertices`).

    ``group (k,)``: the operand of each use (0 for a new one), ``thr (k,)`` its tolerance
    (at least ``tol.linear``).  An unchanged edge use can only be split by a foreign vertex
    (``face_foreign``, the foreign vertices in an unchanged face's box, else
    ``foreign_of[operand of the use]``; a new use has none and is never clear): a use is clear
    when no such vertex lies in its box (:func:`_use_box_array`) padded by both tolerances.  All uses
    of one group against all their foreign vertices in one array test (a plate face with many
    holes has many edges).  ``kept``: the boxes through :func:`_face_use_boxes` (those of the last
    face extended by this one kept).
    """
    clear = np.zeros(len(edges), dtype=bool)
    keys = np.full(len(edges), -1, dtype=np.int64) if face_foreign is not None else group
    # (the distinct keys, ascending, of a face's few uses by a set: np.unique's sort costs more)
    tested = [-1] if face_foreign is not None else [k for k in sorted(set(group.tolist())) if k in foreign_of]
    if kept and tested:
        need = keys == tested[0]
        for key in tested[1:]:  # (np.isin's set-up costs more on a face's few keys)
            need |= keys == key
        face_boxes = _face_use_boxes(edges, need)
    for key in tested:
        rows = np.flatnonzero(keys == key)
        B, none = (face_boxes[0][rows], face_boxes[1][rows]) if kept else _use_box_array([edges[i] for i in rows.tolist()])
        idx, B = rows[~none], B[~none]
        if idx.size == 0:
            continue
        P, ptol = face_foreign if key == -1 else foreign_of[key]
        step = max(1, _CLEAR_CHUNK // max(1, P.shape[0]))
        for s0 in range(0, idx.size, step):
            pad = ptol[:, None] + thr[None, idx[s0 : s0 + step]]  # (m vertices, n uses)
            Bs = B[s0 : s0 + step]
            # (coordinate by coordinate, and reduced over the vertices, the first axis: numpy reduces a
            # short last axis row by row)
            near = np.ones(pad.shape, dtype=bool)
            for j in range(3):
                near &= (P[:, j, None] >= Bs[None, :, 0, j] - pad) & (P[:, j, None] <= Bs[None, :, 1, j] + pad)
            clear[idx[s0 : s0 + step]] = ~near.any(axis=0)
    return clear


#: Use–vertex pairs held at once by :func:`_clear_uses` (memory bound).
_CLEAR_CHUNK = 1 << 18


def _face_use_boxes(edges: list[EdgeSpec], need: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_use_box_array` of the uses ``edges`` of a face (in loop order) in the rows ``need`` (``(k,)``
    bool; the other rows are left unset), ``(k, 2, 3)`` and ``(k,)``.  The rows that the last face boxed here
    with the same first use had boxed (:data:`_FACE_USE_BOXES`; its uses a prefix of ``edges``, use for use)
    are taken in one piece, only the others are boxed: a plate's top gaining a hole every cut keeps its
    other loops' uses first and boxes the last cut's new loop (the new one is not tested, a new use has no
    foreign vertex)."""
    k = len(edges)
    B = np.empty((k, 2, 3))
    none = np.zeros(k, dtype=bool)
    known = np.zeros(k, dtype=bool)
    got = _FACE_USE_BOXES.get(edges[0]) if edges else None
    if got is not None:
        rest, B0, none0, known0 = got
        n = len(rest) + 1
        if n <= k and all(map(operator.is_, rest, edges[1:n])):
            B[:n], none[:n], known[:n] = B0, none0, known0
    todo = np.flatnonzero(need & ~known)
    if todo.size:
        B[todo], none[todo] = _use_box_array([edges[i] for i in todo.tolist()])
        known[todo] = True
    if edges:
        _FACE_USE_BOXES.set(edges[0], (tuple(edges[1:]), _frozen(B), _frozen(none), _frozen(known)))
    return B, none


#: First use of a face -> ``(its other uses, the boxes of :func:`_use_box_array` of its uses, where there is
#: none, which rows are boxed)`` of the last face of many loops boxed with that first use
#: (:func:`_face_use_boxes`).  The value never holds the key (the first use is stored without it).
_FACE_USE_BOXES = IdentityMemo()


def _foreign_in_boxes(lo: np.ndarray, hi: np.ndarray, P: np.ndarray, ptol: np.ndarray,
                      cand: np.ndarray) -> list[np.ndarray]:
    """Per box ``lo[i], hi[i] (3,)``, the points ``P[j]`` of ``cand`` (ascending indices) inside it
    padded by their tolerance ``ptol[j]`` (``lo - ptol <= P <= hi + ptol`` in every coordinate),
    ascending.

    A k-d tree of the candidate points proposes those within a ball around each box's centre
    that holds the whole padded box (half its diagonal plus ``√3`` times the largest tolerance,
    with a margin for round-off); the box test itself decides.  Boxes times points would grow
    with the square of a part's size: every unchanged face of a plate against every vertex (up
    to :data:`_BOX_POINT_PAIRS` pairs, as a box and a cylinder bring, or the four side faces of a plate
    cut by a hundred tools in one call, the box test runs on every pair).
    """
    from scipy.spatial import cKDTree

    n = lo.shape[0]
    if cand.size == 0:
        return [cand] * n
    Q, qt = P[cand], ptol[cand]
    if n * cand.size <= _BOX_POINT_PAIRS:
        # (few boxes and points: the box test on every pair costs less than the tree; the same test)
        # (coordinate by coordinate: numpy's all() over a last axis of 3 runs row by row)
        pad = qt[None, :]
        inside = np.ones((n, cand.size), dtype=bool)
        for j in range(3):
            inside &= (Q[None, :, j] >= lo[:, j, None] - pad) & (Q[None, :, j] <= hi[:, j, None] + pad)
        rows, cols = np.nonzero(inside)
        out = [cand[:0]] * n  # (most boxes hold none: one empty array for them)
        if rows.size:
            ends = np.flatnonzero(np.diff(rows)) + 1
            for a, b in zip([0] + ends.tolist(), ends.tolist() + [rows.size]):
                out[int(rows[a])] = cand[cols[a:b]]
        return out
    centre = 0.5 * (lo + hi)
    half = 0.5 * np.linalg.norm(hi - lo, axis=1)
    scale = np.abs(centre).max(axis=1) + half
    radius = half + 2.0 * float(qt.max()) + 1e-9 * (1.0 + scale)
    hits = cKDTree(Q).query_ball_point(centre, radius, return_sorted=True)
    out = []
    for i, h in enumerate(hits):
        h = np.asarray(h, dtype=np.int64)
        if h.size:
            pad = qt[h, None]
            ok = np.all((Q[h] >= lo[i] - pad) & (Q[h] <= hi[i] + pad), axis=1)
            h = h[ok]
        out.append(cand[h])
    return out


#: Up to this many box–point pairs :func:`_foreign_in_boxes` tests every pair (measured: 4 boxes and 1 200
#: points 0.14 against 0.39 ms by the tree, 4 and 4 800 0.34 against 1.7; about even at 30 000 pairs).
_BOX_POINT_PAIRS = 1 << 15


def _use_box_array(edges: list[EdgeSpec]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_edge_boxes` of each use as one array, cached per use (an EdgeSpec is immutable; the uses of
    the faces a Boolean result carries over to the next Boolean are the same objects, ``sew.sewn_from``, so
    their boxes are computed once for a chain of cuts): ``(k, 2, 3)`` boxes (rows ``-inf, inf`` where there
    is none) and ``(k,)`` bool where there is none.  The uses not cached yet are boxed together and their rows
    filled from that batch in one assignment (an operand of a hundred tools brings a thousand new
    uses: stacking their row views again cost more than boxing them)."""
    n = len(edges)
    out = np.empty((n, 2, 3))
    none = np.zeros(n, dtype=bool)
    got = _USE_BOXES.get_many(edges)
    cached = [k for k, b in enumerate(got) if b is not None]
    if cached:
        rows = [k for k in cached if got[k] is not _NO_BOX]
        if rows:
            out[rows] = np.concatenate([got[k] for k in rows]).reshape(-1, 2, 3)  # (np.stack costs more)
        none[[k for k in cached if got[k] is _NO_BOX]] = True
    if len(cached) < n:
        todo = [k for k, b in enumerate(got) if b is None]
        boxes, boxed = _edge_box_array([edges[k] for k in todo])
        out[todo] = boxes
        _USE_BOXES.set_many([edges[k] for k in todo],
                            [box if ok else _NO_BOX for box, ok in zip(boxes, boxed.tolist())])
        none[todo] = ~boxed
    out[none] = _NO_BOX_ROW
    return out, none


#: The row :func:`_use_box_array` gives a use without a box.
_NO_BOX_ROW = np.array([[-np.inf] * 3, [np.inf] * 3])


_NO_BOX = object()
#: Edge use -> its box of :func:`_edge_boxes` (``_NO_BOX`` for none).
_USE_BOXES = IdentityMemo()


def _cluster_max(X: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Per point, the largest tolerance in its cluster (points within ``max(tol_i, tol_j)``, transitively), as sewing merges them."""
    if tol.size == 0 or tol.min() == tol.max():
        return tol.copy()  # one tolerance: every cluster's largest is that
    label = point_clusters(X, tol)
    top = np.zeros(int(label.max()) + 1)
    np.maximum.at(top, label, tol)
    return top[label]


# ---------------------------------------------------------------------- merge
def _merge(faces: list[FaceSpec], t: Tolerance) -> list[FaceSpec]:
    """Merge neighbouring faces on one surface with one sense (see the module docstring)."""
    return _merge_faces(faces, t)


def _same_surface(S1, S2, t: Tolerance) -> bool:
    if S1 is S2:
        return True
    if type(S1) is not type(S2):
        return False
    try:
        return bool(S1.is_close(S2, t))
    except (CoonsError, AttributeError, TypeError):
        return False


def _merge_faces(faces: list[FaceSpec], t: Tolerance) -> list[FaceSpec]:
    """Repeatedly fuse two faces that share an edge use pair on one surface with one sense.

    A list of faces most of which the last merge returned (a plate cut again: its hole walls)
    first tries only the pairs that involve another face (:func:`_merge_new`); should one of them
    merge, or no such record apply, every pair is searched (:func:`_merge_all`).
    """
    faces = list(faces)
    out = _merge_new(faces, t)
    return _merge_all(faces, t) if out is None else out


def _merge_all(faces: list[FaceSpec], t: Tolerance) -> list[FaceSpec]:
    """:func:`_merge_faces` over every pair of uses: the pairs are searched again after each merge."""
    from scipy.spatial import cKDTree

    failed: set[tuple] = set()  # pairs of uses already tried (their faces are kept alive in ``seen``)
    seen: list[tuple[FaceSpec, FaceSpec]] = []
    # The uses' points come from the per-face tables (:func:`~coons.topology.sew.use_points`):
    # faces carried over from an operand are not evaluated again, a merged face once.
    while True:
        tables = _face_uses(faces)
        counts = [len(x.where) for x in tables]
        if sum(counts) < 2:
            return faces
        face_of = np.repeat(np.arange(len(faces)), counts)
        W = np.concatenate([x.where for x in tables])  # loop, position, loop length
        tol = np.concatenate([x.ranges[:, 2] for x in tables])
        P3 = np.concatenate([x.points for x in tables])  # start, end, mid
        tree = cKDTree(P3[:, 2])
        pairs = tree.query_pairs(r=max(t.linear, 1e-12), output_type="ndarray").reshape(-1, 2)
        kind = _surface_kinds(faces)[face_of]
        face_first = np.cumsum(counts) - counts  # (each face's first row in P3)
        hit = _first_merge(faces, t, pairs, P3, W, tol, face_of, kind, face_first, counts, failed, seen)
        if hit is None:
            _settle(faces, t, P3, W, tol, kind, face_of, tree)
            return faces
        fp, fq, merged = hit
        faces = [f for k, f in enumerate(faces) if k not in (fp, fq)] + [merged]


#: Surface type -> a number, by which the merge compares the faces' surface types row by row.
_SURFACE_KINDS: dict[type, int] = {}


def _surface_kinds(faces: list[FaceSpec]) -> np.ndarray:
    """``(F,)`` int64: each face's surface type as its number in :data:`_SURFACE_KINDS`."""
    return np.array([_SURFACE_KINDS.setdefault(type(f.surface), len(_SURFACE_KINDS)) for f in faces],
                    dtype=np.int64)


def _first_merge(faces: list[FaceSpec], t: Tolerance, pairs: np.ndarray, P3: np.ndarray, W: np.ndarray,
                 tol: np.ndarray, face_of: np.ndarray, kind: np.ndarray, face_first: np.ndarray,
                 counts, failed: set, seen: list) -> tuple[int, int, FaceSpec] | None:
    """Try the candidate pairs of uses ``pairs (m, 2)`` in turn: ``(fp, fq, A ∪ B)`` for the first
    that merges faces ``fp`` and ``fq``, None when none does (each failure remembered in
    :data:`_MERGE_FAILED`).

    Rows of the use table: ``P3 (n, 3, 3)`` start, end and mid point, ``W (n, 3)`` loop, position
    and loop length, ``tol (n,)``, ``face_of (n,)`` the face, ``kind (n,)`` its surface type's
    number; each face's rows in loop order from ``face_first[f]``, ``counts[f]`` of them.
    ``failed`` (keys of the pairs tried) and ``seen`` (their faces, which keeps the ids in the keys
    from being reused) carry over between the calls of one merge.
    """
    # Only uses of two faces on surfaces of one type that run between the same two points
    # the opposite way can be merged across; the test of the loop below, all pairs at once
    # with a margin (it passes every pair the exact test passes, which then decides).
    p, q = pairs[:, 0], pairs[:, 1]
    reach = np.square(np.maximum(np.maximum(tol[p], tol[q]), t.linear) * (1.0 + 1e-9))
    keep = ((face_of[p] != face_of[q]) & (kind[p] == kind[q])
            & (np.square(P3[p, 0] - P3[q, 1]).sum(axis=1) <= reach)
            & (np.square(P3[p, 1] - P3[q, 0]).sum(axis=1) <= reach))
    pairs = pairs[keep]
    # (only the candidate pairs' rows as Python lists: a plate's thousands of uses are not converted)
    fpq, upq = face_of[pairs].tolist(), W[pairs, :2].tolist()
    # Pairs tried before, in this pass or by an earlier Boolean on the same two face specs,
    # are dropped before the batched full-period test (a plate cut hole by hole brings every
    # earlier hole's two wall halves again).
    live = []
    memos = _MERGE_FAILED.get_many([faces[fp] for fp, _ in fpq])
    for i, ((fp, fq), (up, uq), known) in enumerate(zip(fpq, upq, memos)):
        A, B = faces[fp], faces[fq]
        up, uq = tuple(up), tuple(uq)
        if (id(A), up, id(B), uq) in failed:
            continue
        known = known.get(id(B)) if known is not None else None
        if known is not None and known[0]() is B and (up, uq, t) in known[1]:
            continue  # found unmergeable by an earlier Boolean on the same two face specs
        live.append(i)
    if not live:
        return None
    pairs = pairs[live]
    fpq = [fpq[i] for i in live]
    upq = [upq[i] for i in live]
    _prefill_uv_extents([faces[f] for f in sorted({f for fg in fpq for f in fg})
                         if getattr(faces[f].surface, "period_u", None) or getattr(faces[f].surface, "period_v", None)])
    wraps = _wrapping_pairs(faces, fpq, upq)
    for (p, q), (fp, fq), (up, uq), wrap in zip(pairs.tolist(), fpq, upq, wraps):
        A, B = faces[fp], faces[fq]
        up, uq = tuple(up), tuple(uq)
        key = (id(A), up, id(B), uq)
        if key in failed:
            continue
        memo = (up, uq, t)
        failed.add(key)  # (if the merge succeeds both faces are gone and the key is never seen again)
        seen.append((A, B))  # keeps the ids in the keys from being reused by new faces
        ea, eb = A.loops[up[0]][up[1]], B.loops[uq[0]][uq[1]]
        Pa, Pb = P3[p], P3[q]
        thr = max(t.linear, ea.tol or 0.0, eb.tol or 0.0)
        d0, d1 = Pa[0] - Pb[1], Pa[1] - Pb[0]
        # (np.linalg.norm of a vector is the root of its dot product with itself: the same floats, without
        # its set-up)
        if not (math.sqrt(d0.dot(d0)) <= thr and math.sqrt(d1.dot(d1)) <= thr):
            continue
        probes = P3[face_first[fq] : face_first[fq] + min(int(counts[fq]), _MOVED_PROBES), 0]  # (B's own rows)
        if not wrap and _off_plane(A, B, probes, t):
            _merge_failed(A, B, memo)
            continue
        merged = None if wrap else _merged_pair(A, B, up, uq, t)
        if merged is None:
            _merge_failed(A, B, memo)
            continue
        return fp, fq, merged
    return None


class _Settled:
    """Faces of which no two merge (every candidate pair of uses among them tried, none merging),
    for the tolerance ``t`` (:data:`_MERGE_SETTLED`).

    Each face has a number ``k``; ``member[k]`` says whether it still belongs: a face absent from a
    merge that adds faces to the record leaves it (its pairs with the faces added were not tried).
    The faces' use rows as :func:`_first_merge` reads them, in layers (one per merge that added
    faces): ``(P3, W, tol, kind, face, tree)``, ``face`` the rows' face numbers (each face's rows
    together, in loop order) and ``tree`` a k-d tree of their mid points.
    """

    __slots__ = ("t", "member", "layers")


#: Face spec -> ``(_Settled, its number there)``.  Whether two faces merge across two uses depends
#: only on the two specs, the uses and the tolerance, and which pairs are candidates only on their
#: use rows (functions of each spec), so two members of one record are not tried again.
_MERGE_SETTLED = IdentityMemo()
#: A record is rebuilt as one layer of its members' rows when it has more layers than this.
_SETTLED_LAYERS = 4


def _settle(faces: list[FaceSpec], t: Tolerance, P3: np.ndarray, W: np.ndarray, tol: np.ndarray,
            kind: np.ndarray, face_of: np.ndarray, tree) -> None:
    """Record in :data:`_MERGE_SETTLED` that no two of ``faces`` merge: a new :class:`_Settled` of
    one layer, their rows (``face_of`` the rows' faces) and the tree of the rows' mid points."""
    rec = _Settled()
    rec.t, rec.member, rec.layers = t, [True] * len(faces), [(P3, W, tol, kind, face_of, tree)]
    _MERGE_SETTLED.set_many(faces, [(rec, k) for k in range(len(faces))])


def _merge_new(faces: list[FaceSpec], t: Tolerance) -> list[FaceSpec] | None:
    """``faces`` when no pair of them merges, decided by trying only the pairs of uses that involve
    a face not in the record (:data:`_MERGE_SETTLED`) that holds most of them; None when no record
    applies or some pair merges (then :func:`_merge_all` decides: which merge comes first
    depends on the order of its search).  The faces tried join the record, those absent leave it.

    The record's faces take their use rows and the trees of their mid points from it; the other
    faces' rows are read (:func:`~coons.topology.sew._face_uses`) and searched against both.  The
    search radius is widened by a round-off margin: more candidates than :func:`_merge_all`'s
    only cost their tests, whose outcome decides nothing beyond themselves.
    """
    from scipy.spatial import cKDTree

    if len(set(map(id, faces))) != len(faces):
        return None  # (a face twice: its two copies are a pair of faces to search)
    got = _MERGE_SETTLED.get_many(faces)
    groups: dict[int, list[int]] = {}
    for i, g in enumerate(got):
        if g is not None and g[0].member[g[1]] and g[0].t == t:
            groups.setdefault(id(g[0]), []).append(i)
    if not groups:
        return None
    G = max(groups.values(), key=len)
    rec = got[G[0]][0]
    if len(G) == len(faces):
        return faces
    in_g = [False] * len(faces)
    for i in G:
        in_g[i] = True
    R = [i for i, x in enumerate(in_g) if not x]
    tables = _face_uses([faces[i] for i in R])
    counts_r = [len(x.where) for x in tables]
    n_r = sum(counts_r)
    # The members' rows, renumbered to ``faces`` (rows of faces absent here dropped).
    number = np.full(len(rec.member), -1, dtype=np.int64)
    k_g = [got[i][1] for i in G]
    number[k_g] = G
    alive = [number[layer[4]] >= 0 for layer in rec.layers]
    face_of = np.concatenate([np.repeat(np.array(R, dtype=np.int64), counts_r)]
                             + [number[layer[4][a]] for layer, a in zip(rec.layers, alive)])
    own = (np.concatenate([x.points for x in tables]), np.concatenate([x.where for x in tables]),
           np.concatenate([x.ranges[:, 2] for x in tables]),
           np.repeat(_surface_kinds([faces[i] for i in R]), counts_r))
    P3, W, tol, kind = (np.concatenate([own[c]] + [layer[c][a] for layer, a in zip(rec.layers, alive)])
                        for c in range(4))
    pairs = np.zeros((0, 2), dtype=np.int64)
    if n_r:
        r = max(t.linear, 1e-12) * (1.0 + 1e-6)
        new = cKDTree(P3[:n_r, 2])
        found = [new.query_pairs(r=r, output_type="ndarray").reshape(-1, 2)]
        at = n_r  # (each layer's first row here)
        for layer, a in zip(rec.layers, alive):
            near = new.sparse_distance_matrix(layer[5], r, output_type="ndarray")
            keep = a[near["j"]]
            row = np.cumsum(a) - 1 + at  # (a layer row's row here)
            found.append(np.stack([near["i"][keep], row[near["j"][keep]]], axis=1))
            at += int(np.count_nonzero(a))
        pairs = np.concatenate(found).astype(np.int64)
        # Each face's rows are together, in loop order.
        first = np.flatnonzero(np.concatenate([[True], face_of[1:] != face_of[:-1]]))
        face_first = np.zeros(len(faces), dtype=np.int64)
        counts = np.zeros(len(faces), dtype=np.int64)
        face_first[face_of[first]] = first
        counts[face_of[first]] = np.diff(np.append(first, face_of.size))
        try:
            if _first_merge(faces, t, pairs, P3, W, tol, face_of, kind, face_first, counts, set(), []) is not None:
                return None
        except (CoonsError, ValueError, ArithmeticError):
            return None  # (the search of every pair raises it, or merges first and never meets this pair)
    # The faces tried join the record; the members absent leave it.
    member = [False] * len(rec.member)
    for k in k_g:
        member[k] = True
    k_r = list(range(len(member), len(member) + len(R)))
    member += [True] * len(R)
    rec.member = member
    if len(rec.layers) >= _SETTLED_LAYERS:
        number = np.empty(len(faces), dtype=np.int64)
        number[G], number[R] = k_g, k_r
        rec.layers = [(P3, W, tol, kind, number[face_of], cKDTree(P3[:, 2]))]
    elif n_r:
        rec.layers.append((P3[:n_r], W[:n_r], tol[:n_r], kind[:n_r],
                           np.repeat(np.array(k_r, dtype=np.int64), counts_r), new))
    _MERGE_SETTLED.set_many([faces[i] for i in R], [(rec, k) for k in k_r])
    return faces


#: ``A -> B -> {(loop, position in A, loop, position in B, tol)}``: pairs of shared uses of two
#: face specs that :func:`_merge_faces` found it cannot merge.  The test depends only on the two
#: (immutable) specs, the two uses and the tolerance, so a Boolean result's faces that pass through
#: the next Boolean unchanged (the same spec objects, see ``sew.sewn_from``) are not tried again: the two
#: halves of every hole's wall in a plate would otherwise be re-tested by every later cut.
_MERGE_FAILED = IdentityMemo()


def _merge_failed(A: FaceSpec, B: FaceSpec, memo: tuple) -> None:
    """Remember in :data:`_MERGE_FAILED` that ``A`` and ``B`` do not merge across the uses of ``memo``.

    Per A, a dict on ``id(B)`` holding a weak reference to B (checked on look-up: a recycled id
    never finds another face's entry) and the set of failed use pairs.
    """
    known = _MERGE_FAILED.setdefault(A, dict)
    got = known.get(id(B))
    if got is None or got[0]() is not B:
        got = known[id(B)] = (weakref.ref(B), set())
    got[1].add(memo)


def _off_plane(A: FaceSpec, B: FaceSpec, starts: np.ndarray, t: Tolerance) -> bool:
    """Whether :func:`_merged_pair` is sure to return None for two faces on distinct planes because
    B's boundary leaves A's plane: :func:`_moved`'s first test in Python floats (two faces of a box
    meeting at an edge; numpy on the few probes cost more than the test).

    ``starts``: the start points of B's first uses in loop order (its use table,
    :func:`~coons.topology.sew._face_uses`), at most :data:`_MOVED_PROBES`.  A point counts as off
    only when its distance to the plane exceeds :func:`_moved`'s threshold by more than a
    round-off margin (the table's points and the plane's projection may differ from ``_moved``'s
    in the last bits), so a True here is a None there; False decides nothing.
    """
    S = A.surface
    if type(S) is not PlanarSurface or type(B.surface) is not PlanarSurface or S is B.surface:
        return False
    o, n = S.origin.tolist(), S.axis.tolist()
    # Normals farther apart than the angular tolerance (with room for round-off) are not close
    # (``is_close`` compares the axes within ``t.angular``): no need to ask it.
    turned = math.dist(n, B.surface.axis.tolist()) > 2.0 * t.angular + 1e-12
    scale = 1.0 + max(abs(x) for x in o)
    ends = itertools.chain.from_iterable(B.loops)
    off = False
    for (x, y, z), e in zip(starts.tolist(), ends):
        d = abs((x - o[0]) * n[0] + (y - o[1]) * n[1] + (z - o[2]) * n[2])
        # (10x the use's tolerance, as _moved, plus a round-off margin; where coordinates are large the
        # margin may exceed it, which only makes the answer False, deciding nothing)
        if d > 10.0 * max(t.linear, e.tol or 0.0) + 1e-9 * (scale + abs(x) + abs(y) + abs(z)):
            off = True
            break
    # Two planes that compare close are one surface to _merged_pair, whatever their faces' extent.
    return off and (turned or not _same_surface(S, B.surface, t))


def _merged_pair(A: FaceSpec, B: FaceSpec, up: tuple[int, int], uq: tuple[int, int], t: Tolerance) -> FaceSpec | None:
    """The face ``A ∪ B`` across use ``up = (loop, position)`` of A and ``uq`` of B (which run
    between the same points the opposite way), or None when they do not merge: other
    surfaces, other senses, other parameter-plane images of the shared edge, a full period.

    A function of the two specs, the two uses and ``t`` only (memoised in :data:`_MERGE_FAILED`).
    """
    if not _same_surface(A.surface, B.surface, t):
        # The same point set in another parametrisation: B's p-curves re-expressed on A's surface.
        B = _moved_to(B, A.surface, t)
        if B is None:
            return None
    if A.sense != B.sense:
        return None
    # The shared edge must have the same parameter-plane image on both: shift B by whole
    # periods when they differ by one (a face pair across u = 0 of a cylinder).
    ea, eb = A.loops[up[0]][up[1]], B.loops[uq[0]][uq[1]]
    # (three samples each unless both p-curves are straight: one straight and one curved image of
    # the shared edge are compared at the same three points)
    mixed = isinstance(ea.pcurve, Line2D) != isinstance(eb.pcurve, Line2D)
    ua, ub = _edge_uv(ea, A.surface, 3, all_n=mixed), _edge_uv(eb, A.surface, 3, all_n=mixed)[::-1]
    offset = np.mean(ua - ub, axis=0)
    # (_wrapping_pairs mirrors this test for many pairs at once: keep the two in step)
    if _wraps(A, B, _whole_periods(A.surface, offset)):
        return None  # (the cheap form of _fuse's own full-period test, before B is shifted: two half cylinders)
    B = _period_shifted(B, A.surface, offset)
    if B is None:
        return None
    eb = B.loops[uq[0]][uq[1]]
    ub = _edge_uv(eb, A.surface, 3, all_n=mixed)[::-1]
    if np.max(np.abs(ua - ub)) > 1e-9 * (1.0 + np.max(np.abs(ua))):
        return None
    return _fuse(A, B, up, uq, t)


def _wrapping_pairs(faces: list[FaceSpec], fpq: list[list[int]], upq: list[list[list[int]]]) -> list[bool]:
    """Per candidate pair of :func:`_merge_faces` (faces ``fpq[i]``, uses ``upq[i]``): whether
    :func:`_merged_pair` returns None at its full-period test (:func:`_wraps`), decided for all
    pairs at once (a plate drilled in one call brings two hundred pairs of half cylinders).

    Only pairs that reach that test on the fast path are decided: one surface object, one sense,
    straight p-curves on the shared use (sampled by their ends), a periodic surface and both
    faces' :func:`_uv_extent`; False for every other pair (which :func:`_merged_pair` then
    tests).  The expressions are those of :func:`_merged_pair`, :func:`_whole_periods` and
    :func:`_wraps` element by element (``Line2D.evaluate``, the mean of two rows, ``round``,
    ``max``/``min``), so the same floats and the same decisions.
    """
    out = [False] * len(fpq)
    rows, ends, origin, direction, period, ext = [], [], [], [], [], []
    for i, ((fp, fq), (up, uq)) in enumerate(zip(fpq, upq)):
        A, B = faces[fp], faces[fq]
        S = A.surface
        if S is not B.surface or A.sense != B.sense:
            continue
        per = (getattr(S, "period_u", None) or 0.0, getattr(S, "period_v", None) or 0.0)
        if not (per[0] or per[1]):
            continue
        ea, eb = A.loops[up[0]][up[1]], B.loops[uq[0]][uq[1]]
        if type(ea.pcurve) is not Line2D or type(eb.pcurve) is not Line2D:
            continue
        xa, xb = _uv_extent(A), _uv_extent(B)
        if not xa or not xb:
            continue
        rows.append(i)
        ends.append(((ea.t0, ea.t1), (eb.t0, eb.t1)))
        origin.append((ea.pcurve.origin, eb.pcurve.origin))
        direction.append((ea.pcurve.direction, eb.pcurve.direction))
        period.append(per)
        ext.append(xa + xb)
    if not rows:
        return out
    T = np.array(ends)  # (m, 2 uses, 2 ends)
    U = np.array(origin)[:, :, None, :] + T[..., None] * np.array(direction)[:, :, None, :]  # (m, 2, 2, 2)
    offset = np.mean(U[:, 0] - U[:, 1, ::-1], axis=1)  # (_merged_pair: B's use reversed)
    P = np.array(period)
    periodic = P > 0.0
    shift = np.where(periodic, P * np.round(offset / np.where(periodic, P, 1.0)), 0.0)
    X = np.array(ext)  # (m, 4, 2): A's lo, hi, B's lo, hi
    span = np.maximum(X[:, 1], X[:, 3] + shift) - np.minimum(X[:, 0], X[:, 2] + shift)
    wraps = np.any(periodic & (span >= P - 1e-9 * P), axis=1).tolist()
    for i, w in zip(rows, wraps):
        out[i] = w
    return out


def _wraps(A: FaceSpec, B: FaceSpec, shift: np.ndarray | None = None) -> bool:
    """Whether faces A and B (B's p-curves on A's surface, moved by ``shift (2,)`` when given: the whole
    periods :func:`_period_shifted` would move them by) together span a full period of a periodic parameter.

    The samples are a subset of those :func:`_fuse` tests, so this never rejects a merge that
    ``_fuse`` would make (up to the round-off of adding the shift before or after evaluating).
    """
    S = A.surface
    pers = [(k, getattr(S, name, None)) for k, name in ((0, "period_u"), (1, "period_v"))]
    pers = [(k, p) for k, p in pers if p]
    if not pers:
        return False
    ea, eb = _uv_extent(A), _uv_extent(B)
    if ea is not None and eb is not None:
        # The ptp of the stacked samples below, from each face's extremes (adding the shift
        # after taking an extreme rounds to the same float: rounding is monotone).
        sh = (0.0, 0.0) if shift is None else shift.tolist()
        return any(max(ea[1][k], eb[1][k] + sh[k]) - min(ea[0][k], eb[0][k] + sh[k]) >= p - 1e-9 * p for k, p in pers)
    UB = _uses_uv([e for loop in B.loops for e in loop], S, 5)
    U = np.concatenate([_uses_uv([e for loop in A.loops for e in loop], S, 5), UB if shift is None else UB + shift])
    return any(float(np.ptp(U[:, k])) >= p - 1e-9 * p for k, p in pers)


#: Face spec -> the extremes ``((u_min, v_min), (u_max, v_max))`` of its uses' ``_uses_uv(..., 5)``
#: samples (:func:`_uv_extent`; faces whose uses all have a p-curve, so that no surface enters).
_UV_EXTENT = IdentityMemo()


def _uv_extent(A: FaceSpec) -> tuple | None:
    """The extremes of the parameter-plane samples :func:`_wraps` takes of face ``A`` (cached per
    spec, :func:`_prefill_uv_extents`), or None when a use has no p-curve."""
    got = _UV_EXTENT.get(A)
    if got is None:
        _prefill_uv_extents([A])
        got = _UV_EXTENT.get(A)
    return got or None


def _prefill_uv_extents(faces: list[FaceSpec]) -> None:
    """:func:`_uv_extent` of the faces not cached yet, their uses evaluated together (the merge
    of a plate drilled in one call tries two hundred pairs of half-cylinders).

    Per use the samples of :func:`_uses_uv` (``n = 5``): a straight or trigonometric p-curve by
    :func:`~coons.kernel.onsurface.curve_derivatives` at the same parameters, any other by
    :func:`_edge_uv`; their extremes are reduced per face.
    """
    todo = [f for f in dict.fromkeys(faces) if _UV_EXTENT.get(f) is None and f.loops]
    if not todo:
        return
    good = [all(e.pcurve is not None for loop in f.loops for e in loop) for f in todo]
    for f, ok in zip(todo, good):
        if not ok:
            _UV_EXTENT.set(f, ())  # (falsy: the samples depend on the surface)
    todo = [f for f, ok in zip(todo, good) if ok]
    if not todo:
        return
    uses = [e for f in todo for loop in f.loops for e in loop]
    lo = np.empty((len(uses), 2))
    hi = np.empty((len(uses), 2))
    kinds = [Line2D if isinstance(e.pcurve, Line2D) else Trig2D if isinstance(e.pcurve, Trig2D) else None
             for e in uses]  # (as _uses_uv tells them apart)
    for kind, k in ((Line2D, 2), (Trig2D, 5)):
        rows = [i for i, c in enumerate(kinds) if c is kind]
        if rows:
            ends = np.array([(uses[i].t0, uses[i].t1) for i in rows])
            T = ends if k == 2 else np.linspace(ends[:, 0], ends[:, 1], k, axis=1)
            U = curve_derivatives([uses[i].pcurve for i in rows], T, 0, 2)[:, :, 0]
            lo[rows], hi[rows] = _middle_extremes(U)
    for i, c in enumerate(kinds):
        if c is None:
            U = _edge_uv(uses[i], None, 5)
            lo[i], hi[i] = U.min(axis=0), U.max(axis=0)
    first = np.cumsum([0] + [sum(len(loop) for loop in f.loops) for f in todo[:-1]])
    lo = np.minimum.reduceat(lo, first, axis=0).tolist()
    hi = np.maximum.reduceat(hi, first, axis=0).tolist()
    for f, a, b in zip(todo, lo, hi):
        _UV_EXTENT.set(f, (tuple(a), tuple(b)))


def _uses_uv(edges: list[EdgeSpec], S, n: int) -> np.ndarray:
    """:func:`_edge_uv` of many uses, stacked ``(m, 2)`` in no particular order: straight and
    trigonometric p-curves evaluated together (:func:`~coons.kernel.onsurface.curve_derivatives`),
    the others one by one."""
    trigs = [e for e in edges if isinstance(e.pcurve, Trig2D)]
    parts = [_edge_uv(e, S, n) for e in edges if not isinstance(e.pcurve, (Line2D, Trig2D))]
    lines = [e for e in edges if isinstance(e.pcurve, Line2D)]
    for group, k in ((lines, 2), (trigs, n)):
        if group:
            ends = np.array([(e.t0, e.t1) for e in group])
            T = ends if k == 2 else np.linspace(ends[:, 0], ends[:, 1], k, axis=1)
            parts.append(curve_derivatives([e.pcurve for e in group], T, 0, 2).reshape(-1, 2))
    return np.concatenate(parts) if parts else np.zeros((0, 2))


#: Edge starts of a face tested against another surface before :func:`_moved_to` re-expresses it.
_MOVED_PROBES = 8


def _moved_to(B: FaceSpec, S, t: Tolerance) -> FaceSpec | None:
    """Face B on surface S (the same point set as B's surface), or None when B does not lie on S.

    The p-curves are recomputed by ``pcurve_on`` and the sense follows from comparing the normals
    at an interior point of B.  A function of B, S and ``t`` alone (all immutable): a None is
    remembered (:data:`_NOT_ON`), as a face carried over from an operand meets the same
    neighbouring surface again in every later Boolean (a plate's side faces and its top).
    """
    if any(s is S and u == t for s, u in _NOT_ON.get(B, ())):
        return None
    out = _moved(B, S, t)
    if out is None and is_value(S):
        _NOT_ON.set(B, _NOT_ON.get(B, ()) + ((S, t),))
    return out


#: Face spec -> ``((surface, tol), ...)`` on which :func:`_moved_to` found it does not lie.
_NOT_ON = IdentityMemo()


def _moved(B: FaceSpec, S, t: Tolerance) -> FaceSpec | None:
    """:func:`_moved_to`, computed."""
    from coons.kernel.onsurface import pcurve_on

    try:
        # A cheap necessary test first: B's boundary lies on S when B does (within the edges'
        # tolerances; 10x of margin).  Two faces of a box meeting at an edge fail it at once,
        # without the interior point of a face with many holes.
        ends = [e for loop in B.loops for e in loop][:_MOVED_PROBES]
        Q = np.array([np.asarray(e.curve.evaluate(e.t0), dtype=np.float64).reshape(3) for e in ends])
        thr = 10.0 * np.array([max(t.linear, e.tol or 0.0) for e in ends])
        uvq = np.asarray(S.closest_parameters(Q), dtype=np.float64).reshape(-1, 2)
        if np.any(np.linalg.norm(np.asarray(S.evaluate(uvq[:, 0], uvq[:, 1])).reshape(-1, 3) - Q, axis=1) > thr):
            return None
        P, N = _interior_point(B, t)
        uv = np.asarray(S.closest_parameters(P[None]), dtype=np.float64).reshape(2)
        if np.linalg.norm(np.asarray(S.evaluate(uv[0], uv[1])).reshape(3) - P) > t.linear:
            return None
        n = np.asarray(S.normal(uv[0], uv[1])).reshape(3)
        loops = []
        for loop in B.loops:
            new = []
            for e in loop:
                lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
                pc, dev = pcurve_on(S, e.curve, lo, hi, tol=t)
                ne = EdgeSpec(e.curve, e.t0, e.t1, pc, max(dev, e.tol or 0.0))
                if new:  # keep the loop continuous across periodic parameters
                    end = _edge_uv(new[-1], S, 2)[-1]
                    ne = _shifted_edge(ne, S, end - _edge_uv(ne, S, 2)[0])
                    if ne is None:
                        return None
                new.append(ne)
            loops.append(new)
    except (CoonsError, ValueError, ArithmeticError):
        return None
    return FaceSpec(S, bool(np.dot(n, N) > 0.0), loops)


def _whole_periods(S, offset: np.ndarray) -> np.ndarray:
    """The multiples of S's periods nearest to ``offset`` ``(2,)``, per parameter (0 where not periodic)."""
    shift = np.zeros(2)
    for k, name in ((0, "period_u"), (1, "period_v")):
        per = getattr(S, name, None)
        if per:
            shift[k] = per * np.round(offset[k] / per)
    return shift


def _period_shifted(B: FaceSpec, S, offset: np.ndarray) -> FaceSpec | None:
    """B with its p-curves moved by the whole periods nearest to ``offset`` (None if impossible)."""
    shift = _whole_periods(S, offset)
    if not np.any(shift):
        return B
    loops = []
    for loop in B.loops:
        new = []
        for e in loop:
            ne = _shifted_edge(e, S, shift)
            if ne is None:
                return None
            new.append(ne)
        loops.append(new)
    return FaceSpec(B.surface, B.sense, loops)


def _shifted_edge(e: EdgeSpec, S, offset: np.ndarray) -> EdgeSpec | None:
    """``e`` with its p-curve moved by the whole periods of S nearest to ``offset`` (None if impossible)."""
    shift = _whole_periods(S, offset)
    if not np.any(shift):
        return e
    pc = e.pcurve
    if isinstance(pc, Line2D):
        pc = Line2D(pc.origin + shift, pc.direction)
    elif isinstance(pc, Trig2D):
        pc = Trig2D(pc.center + shift, pc.a, pc.b)
    else:
        return None
    return EdgeSpec(e.curve, e.t0, e.t1, pc, e.tol)


def _fuse(A: FaceSpec, B: FaceSpec, ua: tuple[int, int], ub: tuple[int, int], t: Tolerance) -> FaceSpec | None:
    """The face ``A ∪ B`` across the shared edge uses ``ua`` (in A) and ``ub`` (in B), or None when
    the result would wrap a full period or its loops cannot be rebuilt unambiguously."""
    S = A.surface
    # All edge uses of both faces except the shared pair (and any other pairs they share).
    items = [e for li, loop in enumerate(A.loops) for pi, e in enumerate(loop) if (li, pi) != ua]
    items += [e for li, loop in enumerate(B.loops) for pi, e in enumerate(loop) if (li, pi) != ub]
    ends = np.array([np.asarray(e.curve.evaluate(np.array([e.t0, e.t1]))) for e in items])  # (k, 2, 3)
    mids = np.array([np.asarray(e.curve.evaluate(0.5 * (e.t0 + e.t1))) for e in items])
    k = len(items)
    thr = max([t.linear] + [e.tol or 0.0 for e in items])
    # Cancel further shared pairs (a face pair may share several consecutive edges).
    def near(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(P[:, None, :] - Q[None, :, :], axis=-1) <= thr

    # Use x and use y run along one curve in opposite directions: all (x, y) at once, then the
    # pairs taken greedily in (x, y) order, each use cancelled at most once.
    match = np.triu(near(mids, mids) & near(ends[:, 0], ends[:, 1]) & near(ends[:, 1], ends[:, 0]), 1)
    alive = np.ones(k, dtype=bool)
    for x, y in zip(*np.nonzero(match)):
        if alive[x] and alive[y]:
            alive[x] = alive[y] = False
    idx = np.flatnonzero(alive)
    if idx.size == 0:
        return None
    # Re-link: each use continues with the use starting where it ends (unique, else give up).
    loops, used = [], np.zeros(k, dtype=bool)
    for s in idx.tolist():
        if used[s]:
            continue
        loop, cur = [], s
        while not used[cur]:
            used[cur] = True
            loop.append(items[cur])
            nxt = [y for y in idx.tolist() if not used[y] and np.linalg.norm(ends[y, 0] - ends[cur, 1]) <= thr]
            if not nxt:
                break
            if len(nxt) > 1:
                return None
            cur = nxt[0]
        if np.linalg.norm(ends[cur, 1] - ends[s, 0]) > thr:
            return None
        loops.append(loop)
    rings = [np.concatenate([_edge_uv(e, S, 17) for e in loop]) for loop in loops]
    for per, k2 in ((getattr(S, "period_u", None), 0), (getattr(S, "period_v", None), 1)):
        if per:
            span = max(R[:, k2].max() for R in rings) - min(R[:, k2].min() for R in rings)
            if span >= per - 1e-9 * per:
                return None
    areas = np.array([_shoelace(R) for R in rings]) * (1.0 if A.sense else -1.0)
    outer = np.flatnonzero(areas > 0)
    if outer.size != 1:
        return None  # the union is not one face with holes (or the orientation is unclear)
    o = int(outer[0])
    return FaceSpec(S, A.sense, [loops[o]] + [l for i, l in enumerate(loops) if i != o])


def _shoelace(R: np.ndarray) -> float:
    x, y = R[:, 0], R[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# ---------------------------------------------------------------------- fuse edges
def _fuse_edges(faces: list[FaceSpec], t: Tolerance, points: _UsePoints | None = None) -> list[FaceSpec]:
    """Remove vertices where exactly two edges meet and continue one curve.

    Splitting and merging leave such vertices (the top of the union of two boxes keeps the
    points where the other box's edges ended).  At a vertex with exactly two edge uses leaving
    it, the two uses arriving and leaving in each of its two faces are fused into one when both
    pairs lie on one curve: the same curve object over adjacent ranges with the same p-curve,
    or two collinear :class:`Line` edges whose p-curves are :class:`Line2D` on one line.  Closed
    edges are never created (the vertex stays when the fused edge would end where it starts).
    """
    # The uses' points of the faces as they come (per face spec, cached; a result's faces from its
    # sewing's columns in one take: sew._gathered_uses).
    (P, W), _, per_face = _gathered_uses(faces, ("points", "where"))
    loops: dict[int, list[list[EdgeSpec]]] = {}  # the loops of the faces changed so far, as lists
    points = points if points is not None else _UsePoints()  # only a fused use is new in a round
    for _ in range(64):  # each round removes at least one vertex; a bound against surprises
        if not loops:
            counts, where_a, starts_a = per_face, W[:, :2], P[:, 0]
        else:  # (the changed faces' uses as they are now, the others' rows as they came)
            starts, where = [], []
            for fi, (a, b) in enumerate(itertools.pairwise(np.concatenate([[0], np.cumsum(per_face)]).tolist())):
                fl = loops.get(fi)
                if fl is None:
                    starts.append(P[a:b, 0])
                    where.append(W[a:b, :2])
                else:
                    uses = [e for loop in fl for e in loop]
                    starts.append(points.get(uses)[:, 0])
                    where.append(np.array([(li, pi) for li, loop in enumerate(fl) for pi in range(len(loop))],
                                          dtype=np.int64).reshape(-1, 2))
            counts = [w.shape[0] for w in where]
            where_a = np.concatenate(where)
            starts_a = np.concatenate(starts)
        face_of = np.repeat(np.arange(len(faces)), counts)
        label = point_clusters(starts_a, np.full(starts_a.shape[0], t.linear))
        count = np.bincount(label)
        order = np.argsort(label, kind="stable")  # the uses leaving each vertex, ascending
        first = np.cumsum(count) - count
        fused = False
        for v in np.flatnonzero(count == 2).tolist():
            leaving = order[first[v] : first[v] + 2].tolist()
            plan = []
            for k in leaving:
                fi, li, pi = int(face_of[k]), int(where_a[k, 0]), int(where_a[k, 1])
                loop = loops[fi][li] if fi in loops else faces[fi].loops[li]
                if len(loop) < 3:
                    break
                prev = loop[pi - 1]
                joined = _joined(prev, loop[pi], t)
                if joined is None:
                    break
                plan.append((fi, li, pi, joined))
            if len(plan) != 2 or plan[0][:2] == plan[1][:2]:
                continue
            for fi, li, pi, joined in plan:
                if fi not in loops:
                    loops[fi] = [list(loop) for loop in faces[fi].loops]
                loop = loops[fi][li]
                loop[pi - 1] = joined
                del loop[pi]
            fused = True
            break  # indices changed: recompute
        if not fused:
            break
    # Untouched faces stay the same objects (the next Boolean recognises them, see sew.sewn_from).
    return [FaceSpec(f.surface, f.sense, loops[fi]) if fi in loops else f for fi, f in enumerate(faces)]


class _UsePoints:
    """Start, end and midpoint ``(3, 3)`` of edge uses, by curve object and range, evaluated once.

    Lines and circles in one batch (:func:`~coons.kernel.onsurface.evaluate_curves`, their own
    formulas), other curves once per curve object.  An entry holds its curve, so an ``id`` is
    never that of another curve.
    """

    def __init__(self) -> None:
        self._got: dict[tuple[int, float, float], tuple[object, np.ndarray]] = {}

    def get(self, uses: list[EdgeSpec]) -> np.ndarray:
        """``(k, 3, 3)``: start, end and midpoint of each use."""
        from coons.kernel.onsurface import BATCHED_CURVES, evaluate_curves

        got = self._got
        new: dict[tuple[int, float, float], EdgeSpec] = {}
        for e in uses:
            key = (id(e.curve), e.t0, e.t1)
            if key not in got and key not in new:
                new[key] = e
        if new:
            es = list(new.values())
            simple = [e for e in es if type(e.curve) in BATCHED_CURVES]
            if simple:
                P = evaluate_curves([e.curve for e in simple],
                                    np.array([[e.t0, e.t1, 0.5 * (e.t0 + e.t1)] for e in simple]))
                for e, Pe in zip(simple, P):
                    got[id(e.curve), e.t0, e.t1] = (e.curve, Pe)
            by_curve: dict[int, list[EdgeSpec]] = {}
            for e in es:
                if type(e.curve) not in BATCHED_CURVES:
                    by_curve.setdefault(id(e.curve), []).append(e)
            for group in by_curve.values():
                tt = np.array([[e.t0, e.t1, 0.5 * (e.t0 + e.t1)] for e in group])
                P = np.asarray(group[0].curve.evaluate(tt), dtype=np.float64).reshape(len(group), 3, 3)
                for e, Pe in zip(group, P):
                    got[id(e.curve), e.t0, e.t1] = (e.curve, Pe)
        if not uses:
            return np.empty((0, 3, 3))
        return np.concatenate([got[id(e.curve), e.t0, e.t1][1] for e in uses]).reshape(-1, 3, 3)  # (np.stack costs more)


def _joined(a: EdgeSpec, b: EdgeSpec, t: Tolerance) -> EdgeSpec | None:
    """The single use running ``a`` then ``b`` when both lie on one curve, else None."""
    thr = max(t.linear, a.tol or 0.0, b.tol or 0.0)
    Pa = np.asarray(a.curve.evaluate(np.array([a.t0, a.t1])), dtype=np.float64)
    Pb = np.asarray(b.curve.evaluate(np.array([b.t0, b.t1])), dtype=np.float64)
    if np.linalg.norm(Pa[0] - Pb[1]) <= thr:
        return None  # would close on itself
    tol = None if a.tol is None and b.tol is None else max(a.tol or 0.0, b.tol or 0.0)
    if a.curve is b.curve and a.pcurve is b.pcurve and abs(a.t1 - b.t0) <= 1e-12 * (1.0 + abs(a.t1)) \
            and (a.t1 - a.t0) * (b.t1 - b.t0) > 0:
        return EdgeSpec(a.curve, a.t0, b.t1, a.pcurve, tol)
    if isinstance(a.curve, Line) and isinstance(b.curve, Line) and isinstance(a.pcurve, Line2D) \
            and isinstance(b.pcurve, Line2D):
        t1 = float(np.asarray(a.curve.closest_parameters(Pb[1][None])).reshape(-1)[0])
        if (t1 - a.t1) * (a.t1 - a.t0) <= 0:
            return None
        mid = np.asarray(b.curve.evaluate(0.5 * (b.t0 + b.t1)), dtype=np.float64)
        on = np.asarray(a.curve.evaluate(np.array([t1, float(np.asarray(a.curve.closest_parameters(mid[None])).reshape(-1)[0])])))
        if np.linalg.norm(on[0] - Pb[1]) > thr or np.linalg.norm(on[1] - mid) > thr:
            return None
        uv_end = np.asarray(a.pcurve.evaluate(t1))
        uv_b = np.asarray(b.pcurve.evaluate(b.t1))
        if np.max(np.abs(uv_end - uv_b)) > 1e-9 * (1.0 + np.max(np.abs(uv_b))):
            return None
        return EdgeSpec(a.curve, a.t0, t1, a.pcurve, tol)
    return None


# ---------------------------------------------------------------------- sew
def _sew(faces: list[FaceSpec], t: Tolerance, stage: str = "sew", what: str | None = None) -> Solid:
    """``sew_faces`` with its failure reported as ``BooleanError(stage=stage)``, saying ``what`` was sewn.

    A result that touches itself at a point (a pinch: separate fans of faces around one vertex,
    e.g. a box face tangent to a torus at a saddle point of the tube) is not a manifold; coons
    solids are (as in :mod:`coons.booleans.polyhedral`), so it raises with the point named.
    """
    try:
        return sew_faces(faces, t)
    except CoonsError as exc:
        what = what or f"sewing {len(faces)} selected faces"
        pinch = _pinch(faces, t) if "non-manifold-vertex" in str(exc) else None
        if pinch is not None:
            P, fans = pinch
            raise BooleanError(
                f"{what} failed: the result is not a manifold: {fans} separate fans of faces meet at the vertex "
                f"{P.tolist()} (the result touches itself at a point); coons solids are manifold (expected 1)",
                stage=stage, diagnostics={"faces": len(faces), "vertex": P.tolist(), "fans": fans,
                                          "error": str(exc)}) from exc
        raise BooleanError(f"{what} failed: {type(exc).__name__}: {exc}",
                           stage=stage, diagnostics={"faces": len(faces), "error": str(exc)}) from exc


def _pinch(faces: list[FaceSpec], t: Tolerance) -> tuple[np.ndarray, int] | None:
    """A vertex of the faces around which they form more than one fan: ``(point (3,), fans)``, or None.

    Edge-use ends within their tolerance are one vertex (as ``sew_faces`` merges them); two uses
    are the two sides of one edge when they join the same vertices the opposite way and their
    midpoints agree.  A *corner* is an incoming use and the next use of its loop; the corner at
    the end of use ``k`` and the corner at the end of the mate of ``next(k)`` are neighbours
    around the vertex.  A vertex whose corners fall into several connected groups is a pinch.
    Only run after sewing failed (it evaluates every use once more).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    uses, nxt = [], []
    for f in faces:
        for loop in f.loops:
            n = len(loop)
            nxt.append(len(uses) + (np.arange(n) + 1) % n)
            uses.extend(loop)
    nxt = np.concatenate(nxt).astype(np.int64)
    P = np.array([np.asarray(e.curve.evaluate(np.array([e.t0, e.t1, 0.5 * (e.t0 + e.t1)])), dtype=np.float64)
                  for e in uses])  # (k, 3, 3): start, end, mid
    k = len(uses)
    r = max([t.linear] + [e.tol or 0.0 for e in uses])
    X = np.concatenate([P[:, 0], P[:, 1]])
    pairs = cKDTree(X).query_pairs(r=r, output_type="ndarray")
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(2 * k, 2 * k))
    _, label = connected_components(g, directed=False)
    vs, ve = label[:k], label[k:]
    mate = np.full(k, -1, dtype=np.int64)
    mp = cKDTree(P[:, 2]).query_pairs(r=r, output_type="ndarray")
    if mp.size:
        a, b = mp[:, 0], mp[:, 1]
        ok = (vs[a] == ve[b]) & (ve[a] == vs[b])
        mate[a[ok]], mate[b[ok]] = b[ok], a[ok]
    m = mate[nxt]
    have = m >= 0
    cg = coo_matrix((np.ones(int(have.sum())), (np.flatnonzero(have), m[have])), shape=(k, k))
    _, corner = connected_components(cg, directed=False)
    groups = np.unique(np.stack([ve, corner], axis=1), axis=0)
    fans = np.bincount(groups[:, 0], minlength=int(label.max()) + 1)
    bad = np.flatnonzero(fans > 1)
    if bad.size == 0:
        return None
    v = int(bad[0])
    return X[label == v].mean(axis=0), int(fans[v])


def _kind(spec: FaceSpec) -> str:
    return getattr(spec.surface, "surface_type", type(spec.surface).__name__)
